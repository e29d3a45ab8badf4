"""The whole config's checks, as a run makes them before any long work."""

import ml_collections

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import OptimSettings
from ld_mpc_jax.configs import online_enabled
from ld_mpc_jax.data.sources import DataSpec
from ld_mpc_jax.eval.spec import EvalSettings
from ld_mpc_jax.model.config_checks import check_sections, fields_checked
from ld_mpc_jax.model.settings import LossSettings, ModelSettings, PlanSettings
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.plan.search import validate_plan
from ld_mpc_jax.runs.seed_plan import EvalRounds


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
