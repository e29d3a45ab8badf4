"""The whole config's checks, as a run makes them before any long work: `validate_config` (the
config alone), `checked_plans` (that, and what the run needs of this machine and of the run it
fine-tunes, then each training seed's plan)."""

from typing import Tuple

import ml_collections

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import OptimSettings
from ld_mpc_jax.configs import online_enabled
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.data.sources import DataSpec
from ld_mpc_jax.eval.spec import EvalSettings
from ld_mpc_jax.model.config_checks import check_sections, fields_checked
from ld_mpc_jax.model.settings import LossSettings, ModelSettings, PlanSettings
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.plan.search import validate_plan
from ld_mpc_jax.envs.tasks import Tasks
from ld_mpc_jax.ops.seed_groups import SeedGroups
from ld_mpc_jax.runs.seed_plan import EvalRounds, SeedPlan, seed_plans


def validate_config(config: ml_collections.ConfigDict) -> None:
  """Raises ValueError naming the first field whose value cannot work: every section
  (model.config_checks.check_config's checks, `eval`'s and `data`'s, then the training seeds' and
  the update's), then online training's (OnlineSettings.check) where it is on."""
  fields = config.to_dict()
  with fields_checked(fields):  # Its NaN check after the sections'.
    model, plan = ModelSettings.from_config(config), PlanSettings.from_config(config)
    losses = LossSettings.from_config(config)
    check_sections(fields, model, plan, losses)
    if 'eval' in config:  # Each section's checks beside its settings.
      EvalSettings.from_config(config).check(model.images)
      EvalRounds.from_fields(fields['eval']).check()
      if 'data' in config:
        DataSpec.from_config(config).check()
    validate_plan(plan, model)
    t = config.train
    check_seeds(t.num_seeds, t.get('seed_devices', 1),
                t.data_parallel or ('eval' in config and config.eval.data_parallel))
    OptimSettings.from_config(config).check(losses)
  if online_enabled(config):
    OnlineSettings.from_config(config).check(model, plan)


def checked_plans(config: ml_collections.ConfigDict, workdir: str) -> Tuple[SeedPlan, ...]:
  """Each training seed's plan (runs.seed_plan.seed_plans) once every check a run makes before
  any long work has passed, each a one-line ValueError: the config (`validate_config`), its task
  names, the devices its seeds ask for (`train.seed_devices`), offscreen rendering for a model of
  images, and with `online.init_from` the offline run (or runs) it fine-tunes
  (runs.online.check_init_from), whose data the plans then train on (`config` is left as it is).
  The workdirs are not read: `seed_plan.check_workdirs` checks them against the plans.
  """
  validate_config(config)
  Tasks.from_config(config).check()  # config.task, or every name of config.tasks.
  t = config.train
  SeedGroups(t.num_seeds, t.get('seed_devices', 1))  # Enough devices (one GPU, say).
  if ModelSettings.from_config(config).images:  # Frames are rendered: can they be?
    from ld_mpc_jax.envs.pixels import check_rendering  # pylint: disable=g-import-not-at-top
    check_rendering()
  if online_enabled(config) and config.online.init_from:
    from ld_mpc_jax.runs import online  # pylint: disable=g-import-not-at-top (environments)
    source = online.check_init_from(seed_plans(config, workdir))
    config = with_overrides(config, {})  # A copy, its data the source's.
    config.data.update(source.data.to_dict())
  return seed_plans(config, workdir)


def check_seeds(num_seeds: int, seed_devices: int, data_parallel: bool) -> None:
  """One-line ValueErrors for the training seeds of one process (`config.train.num_seeds`, on
  `seed_devices`: ld_mpc_jax.runs.train_seeds) and the data-parallel update or evaluation
  (`data_parallel`: config.train's or config.eval's), which several seeds cannot use."""
  if not isinstance(num_seeds, int) or isinstance(num_seeds, bool) or num_seeds < 1:
    raise ValueError(f'config.train.num_seeds must be an integer >= 1, got {num_seeds!r}')
  if (not isinstance(seed_devices, int) or isinstance(seed_devices, bool)
      or seed_devices < 0):
    raise ValueError(f'config.train.seed_devices must be an integer >= 0 (0: one device per '
                     f'seed), got {seed_devices!r}')
  if num_seeds > 1 and data_parallel:
    raise ValueError('config.train.num_seeds > 1 runs on one device: set '
                     'config.train.data_parallel and config.eval.data_parallel off')


def load_for_evaluation(workdir: str):
  """(config, ema_params, step) of a training workdir (checkpointing.load_for_evaluation), its
  config refused on one line naming config.json when a hand edit broke any of its checks."""
  return checkpointing.load_for_evaluation(workdir, check=validate_config)
