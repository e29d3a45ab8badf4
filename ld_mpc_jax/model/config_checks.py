"""Checks that a config makes sense, so bad values fail with a message naming the field: every
section but `online` (ld_mpc_jax.online.settings checks it), `eval` and `data` (EvalSettings.check,
EvalRounds.check, DataSpec.check, beside those settings) and the training seeds' and the optimiser's
settings (ld_mpc_jax.runs.checks, above the layers that hold them).

`check_config(config)` is the one entry: it builds the settings once and takes the config as a
plain nested dict (`config.to_dict()`) once. The checks of values are the settings' own
(ld_mpc_jax.model.settings) and, where they need the model's registries, the functions here that
take settings; what must read the config's fields themselves (their presence and types, NaN
anywhere, renamed sections, the batch size and data source that the task checks need) reads that
plain dict: `fields_checked` and `check_sections`.
"""

import contextlib
import math
from typing import Any, Dict, Optional

import ml_collections

from ld_mpc_jax.model import actors, dynamics, objective, proposals
from ld_mpc_jax.model.critics import CRITIC_HEADS, TD_TARGETS
from ld_mpc_jax.model.settings import LossSettings, ModelSettings, PlanSettings
from ld_mpc_jax.ops import legacy

_POSITIVE_INTS = (
    'obs_dim', 'action_dim', 'horizon',
    'model.latent_dim', 'model.encoder_hidden', 'model.width', 'model.num_heads',
    'model.mlp_ratio', 'model.proposal_blocks', 'model.dynamics_blocks', 'model.objective_blocks',
    'model.image_size', 'model.image_channels',
    'plan.num_candidates', 'plan.action_steps', 'plan.dynamics_steps',
    'train.batch_size', 'train.num_steps',
    # Intervals and how many checkpoints to keep (0 would delete every checkpoint, or divide by 0
    # after data collection and compilation; a negative interval would never checkpoint).
    'train.log_every', 'train.checkpoint_every', 'train.eval_every', 'train.max_checkpoints',
)


def check_config(config: ml_collections.ConfigDict) -> None:
  """Raises ValueError naming the first field whose value cannot work, in every section but
  `online`, `eval`, `data`, the training seeds', the optimiser's (OptimSettings.check) and the planner's search
  (plan.search.validate_plan): ld_mpc_jax.runs.checks.validate_config, what a run calls, checks
  them all; elsewhere the settings' builders check the rest: build_plan (under make_plan) the
  search, LearnSettings.from_config (what make_update and create_train_state take) the
  optimiser's."""
  fields = config.to_dict()
  with fields_checked(fields):  # The settings are built once the fields they read are there.
    check_sections(fields, ModelSettings.from_config(config), PlanSettings.from_config(config),
                   LossSettings.from_config(config))


@contextlib.contextmanager
def fields_checked(fields: Dict[str, Any]):
  """The checks of the config's fields themselves (`fields`: config.to_dict()) around the checks
  of its values: before them, no section of an old name and the positive integers by dotted name
  (each present); after them, no NaN field."""
  for old_name in legacy.RENAMED_SECTIONS:  # Only a saved config is migrated (on load).
    if old_name in fields:
      raise ValueError(f'the config has a section {old_name!r}'
                       f'{legacy.renamed_hint(old_name)}; rename it')
  for name in _POSITIVE_INTS:
    v = fields
    for part in name.split('.'):
      if part not in v:
        raise ValueError(f'config is missing field `{name}`')
      v = v[part]
    if not isinstance(v, int) or isinstance(v, bool) or v < 1:
      raise ValueError(f'config.{name} must be an integer >= 1, got {v!r}')
  yield
  for name, v in _leaves(fields):  # NaN passes every `<=` check: the rest refused here.
    if isinstance(v, float) and math.isnan(v):
      raise ValueError(f'config.{name} is NaN; give it a number')


def _leaves(tree: Dict[str, Any], prefix: str = ''):
  """(dotted name, value) of every field of a config as nested dicts, depth first."""
  for k, v in tree.items():
    if isinstance(v, dict):
      yield from _leaves(v, f'{prefix}{k}.')
    else:
      yield f'{prefix}{k}', v


def check_sections(fields: Dict[str, Any], model: ModelSettings, plan: PlanSettings,
                   losses: LossSettings) -> None:
  """Each section's values (the settings' checks, in their order) but `online`'s, `eval`'s,
  `data`'s, the seeds', the optimiser's and the planner's search (ld_mpc_jax.plan.search.validate_plan,
  which the planner's builders and runs.checks.validate_config run). `fields`: config.to_dict(),
  for the batch size and the data source; the settings: the config's (`.from_config`)."""
  model.check_sizes()
  model.check(plan.latent_filter)
  model.check_latent_norm(plan.latent_filter)
  model.check_targets()
  losses.check_weights()
  losses.check_act_target(model)
  check_kinds(model, plan)  # The kinds; what the planner asks of them: plan.search.validate_plan.
  check_critic(model, losses, plan)
  check_tasks(model, fields['train']['batch_size'],
              fields['data']['source'] if 'data' in fields else None)


def check_kinds(model: ModelSettings, plan: PlanSettings) -> None:
  """The model's kinds (their registries) and the planner options each one supports."""
  proposal = proposals.PROPOSALS.get(model.proposal_type)
  dyn = dynamics.DYNAMICS.get(model.dynamics_type)
  if not proposal.sequence and not dyn.one_step:
    raise ValueError(f'config.model.dynamics_type {model.dynamics_type} needs whole action '
                     f'sequences up front, but proposal_type {model.proposal_type!r} proposes one '
                     'action per latent')
  if not dyn.one_step and plan.latent_filter > 0:
    raise ValueError('config.plan.latent_filter needs a one-step dynamics_type (its one-step '
                     f'prediction), not {model.dynamics_type}')
  if not dyn.one_step and plan.num_prior_candidates:
    raise ValueError('config.plan.num_prior_candidates must be 0 with dynamics_type '
                     f'{model.dynamics_type}: actor-prior candidates need a step-by-step rollout')
  if not proposal.sequence and plan.warm_start_steps:
    raise ValueError('config.plan.warm_start_steps must be 0 unless the proposal_type proposes '
                     f'sequences (got {model.proposal_type!r}): only sequences can be shifted')
  if plan.guidance_scale < 0:
    raise ValueError('config.plan.guidance_scale must be >= 0 (0 = off), got '
                     f'{plan.guidance_scale}')
  if plan.guidance_scale and (not proposal.guidable or model.prediction != 'x0'):
    raise ValueError('config.plan.guidance_scale > 0 needs a guidable proposal_type '
                     f"(diffusion_seq, got {model.proposal_type!r}) and diffusion.prediction "
                     "'x0'")
  if plan.guidance_scale and plan.guidance_dynamics_steps < 1:
    raise ValueError('config.plan.guidance_dynamics_steps must be >= 1, '
                     f'got {plan.guidance_dynamics_steps}')


def check_critic(model: ModelSettings, losses: LossSettings, plan: PlanSettings) -> None:
  """config.critic (its kinds' registries) and the planner's robust-selection settings."""
  # plan.pessimism < 0 is optimism (mean + |pessimism| std): online.act_pessimism while acting.
  if not isinstance(plan.dynamics_draws, int) or plan.dynamics_draws < 1:
    raise ValueError(f'config.plan.dynamics_draws must be an integer >= 1, '
                     f'got {plan.dynamics_draws!r}')
  objective.VALUES.get(model.value)
  actor = actors.ACTORS.get(model.actor)
  if losses.td_target not in TD_TARGETS:
    raise ValueError(f'config.critic.td_target must be one of {TD_TARGETS}, '
                     f'got {losses.td_target!r}')
  if actor.value and model.value != actor.value:
    raise ValueError(f'config.critic.actor {model.actor!r} needs the Q ensemble: '
                     f'config.critic.value={actor.value!r}')
  actors.check_log_std_map(model.log_std_map)
  _check_tdmpc2_critics(model, losses, actor.stochastic)
  if not 0.0 < losses.expectile < 1.0:
    raise ValueError(f'config.critic.expectile must be in (0, 1), got {losses.expectile}')
  for name, v in (('num_values', model.num_values), ('num_q', model.num_q),
                  ('rollout_steps', losses.rollout_steps)):
    if not isinstance(v, int) or v < 1:
      raise ValueError(f'config.critic.{name} must be an integer >= 1, got {v!r}')
  if model.value_scale <= 0 or losses.awr_max_weight <= 0 or losses.awr_temperature < 0:
    raise ValueError('config.critic.value_scale and awr_max_weight must be > 0 and '
                     'awr_temperature >= 0')
  if losses.latent_rollout and not dynamics.DYNAMICS.get(model.dynamics_type).one_step:
    raise ValueError('config.critic.latent_rollout needs one-step dynamics; set it False '
                     f'with dynamics_type {model.dynamics_type}')


def _check_tdmpc2_critics(model: ModelSettings, losses: LossSettings, stochastic: bool) -> None:
  """`critic.heads` and `critic.td_target='tdmpc2'`: two-hot heads regress the policy's values
  ('policy' or 'tdmpc2', not the expectile); 'tdmpc2' samples the stochastic actor ('maxq') and
  takes pairs of Q members."""
  if model.critic_heads not in CRITIC_HEADS:
    raise ValueError(f'config.critic.heads must be one of {CRITIC_HEADS}, got '
                     f'{model.critic_heads!r}')
  if model.critic_heads == 'two_hot' and losses.td_target not in ('policy', 'tdmpc2'):
    raise ValueError("config.critic.heads='two_hot' needs config.critic.td_target 'policy' or "
                     f"'tdmpc2' (cross-entropy targets, no expectile), got {losses.td_target!r}")
  if losses.td_target == 'tdmpc2' and (not stochastic or model.num_q < 2):
    raise ValueError("config.critic.td_target='tdmpc2' samples the policy and takes the min of "
                     "two Q members: set config.critic.actor='maxq' and critic.num_q >= 2")


def check_tasks(model: ModelSettings, batch_size: int, source: Optional[str]) -> None:
  """A multi-task model (ld_mpc_jax.model.tasks): every batch (`config.train.batch_size`) splits
  into equal shares per task, and the data (`config.data.source`, None without a data section)
  are the scripted ones."""
  if not model.multitask:
    return
  if batch_size % model.num_tasks:
    raise ValueError(f'config.train.batch_size ({batch_size}) must be a multiple '
                     f'of the number of tasks ({model.num_tasks}): batches hold equal shares per '
                     'task')
  dim = model.task_dim
  if not isinstance(dim, int) or dim < 1:
    raise ValueError(f'config.model.task_dim must be an integer >= 1, got {dim!r}')
  from ld_mpc_jax.data import sources  # pylint: disable=g-import-not-at-top (environments)
  if source != sources.SCRIPTED:
    raise ValueError('multi-task configs (config.tasks) train on the scripted data: '
                     f'config.data.source must be {sources.SCRIPTED}')
