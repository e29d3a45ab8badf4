"""Checks that a config makes sense, so bad values fail with a message naming the field."""

import math
import os

import ml_collections

from ld_mpc_jax.model import exploration, proposals, search, tasks
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
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
# Policy modes (ld_mpc_jax.plan.agent.POLICY_MODES) that can act online: the planner, or the actor
# prior alone (with the executed-action noise).
ACT_MODES = ('plan', 'actor')
# Goal configurations of online training episodes: the 50 of MT1 seed `data.seed`, or a fresh one
# per episode (envs.make_env(random_goals=True)).
TRAIN_GOALS = ('mt1', 'random')


def _get(config, dotted: str):
  node = config
  for part in dotted.split('.'):
    if part not in node:
      raise ValueError(f'config is missing field `{dotted}`')
    node = node[part]
  return node


def _leaves(config, prefix: str = ''):
  """(dotted name, value) of every field of a ConfigDict, depth first."""
  for k, v in config.items():
    if isinstance(v, ml_collections.ConfigDict):
      yield from _leaves(v, f'{prefix}{k}.')
    else:
      yield f'{prefix}{k}', v


def validate_config(config: ml_collections.ConfigDict) -> None:
  """Raises ValueError naming the first field whose value cannot work."""
  _validate_sections(config)
  for name, v in _leaves(config):  # NaN passes every `<=` check: the rest refused here.
    if isinstance(v, float) and math.isnan(v):
      raise ValueError(f'config.{name} is NaN; give it a number')


def _validate_sections(config: ml_collections.ConfigDict) -> None:
  """validate_config's checks of each section's values."""
  for old_name in legacy.RENAMED_SECTIONS:  # Only a saved config is migrated (on load).
    if old_name in config:
      raise ValueError(f'the config has a section {old_name!r}'
                       f'{legacy.renamed_hint(old_name)}; rename it')
  for name in _POSITIVE_INTS:
    v = _get(config, name)
    if not isinstance(v, int) or isinstance(v, bool) or v < 1:
      raise ValueError(f'config.{name} must be an integer >= 1, got {v!r}')
  m = config.model
  if m.width % m.num_heads or m.width % 2:
    raise ValueError(f'config.model.width ({m.width}) must be even (Fourier embeddings) and '
                     f'divisible by config.model.num_heads ({m.num_heads})')
  if m.num_bins < 2 or not m.vmin < m.vmax:
    raise ValueError(f'config.model.num_bins must be >= 2 and vmin < vmax, got '
                     f'{m.num_bins}, [{m.vmin}, {m.vmax}]')
  if not 0.0 <= m.dropout < 1.0:
    raise ValueError(f'config.model.dropout must be in [0, 1), got {m.dropout}')
  model = ModelSettings.from_config(config)
  model.check(config.plan.latent_filter)
  if not 0.0 < config.gamma <= 1.0:
    raise ValueError(f'config.gamma must be in (0, 1], got {config.gamma}')
  if config.diffusion.prediction not in ('x0', 'eps'):
    raise ValueError(f"config.diffusion.prediction must be 'x0' or 'eps', got "
                     f'{config.diffusion.prediction!r}')
  if config.loss.w_progress < 0:
    raise ValueError(f'config.loss.w_progress must be >= 0, got {config.loss.w_progress}')
  _validate_eval_and_data(config)
  _validate_variant(config)  # The kinds, then what the planner asks of them.
  search.validate_plan(PlanSettings.from_config(config), model)
  _validate_critic(config)
  _validate_online(config)
  _validate_tasks(config)
  t = config.train
  if not isinstance(t.num_seeds, int) or isinstance(t.num_seeds, bool) or t.num_seeds < 1:
    raise ValueError(f'config.train.num_seeds must be an integer >= 1, got {t.num_seeds!r}')
  devices = t.get('seed_devices', 1)
  if not isinstance(devices, int) or isinstance(devices, bool) or devices < 0:
    raise ValueError(f'config.train.seed_devices must be an integer >= 0 (0: one device per '
                     f'seed), got {devices!r}')
  if t.num_seeds > 1 and (t.data_parallel or config.eval.data_parallel):
    raise ValueError('config.train.num_seeds > 1 runs on one device: set '
                     'config.train.data_parallel and config.eval.data_parallel off')
  if not 0.0 <= t.ema_decay < 1.0:
    raise ValueError(f'config.train.ema_decay must be in [0, 1), got {t.ema_decay}')
  if 'reward_balance' in config.loss and not 0.0 <= config.loss.reward_balance <= 1.0:
    raise ValueError(f'config.loss.reward_balance must be in [0, 1], got '
                     f'{config.loss.reward_balance!r}')
  if 'obs_noise_aug' in t and not 0.0 <= t.obs_noise_aug < float('inf'):
    raise ValueError(f'config.train.obs_noise_aug must be a std >= 0, got {t.obs_noise_aug!r}')
  if t.learning_rate <= 0 or t.grad_clip <= 0 or t.warmup_steps < 0:
    raise ValueError('config.train.learning_rate and grad_clip must be > 0 and warmup_steps '
                     f'>= 0, got {t.learning_rate}, {t.grad_clip}, {t.warmup_steps}')


def _validate_eval_and_data(config: ml_collections.ConfigDict) -> None:
  """config.eval (policies, episodes, splits, batching) and config.data's source."""
  if 'eval' in config:
    if not all(isinstance(m, str) for m in config.eval.baselines):
      raise ValueError(f'config.eval.baselines must name policy modes, got '
                       f'{config.eval.baselines}')  # runs.Run checks them: agent.POLICY_MODES
  if 'eval' in config and config.eval.episodes < 0:
    raise ValueError(f'config.eval.episodes must be >= 0 (0 skips evaluation), '
                     f'got {config.eval.episodes}')
  if 'eval' in config:
    e = config.eval
    bad = set(e.splits) - {'held_out', 'train'}
    if bad or not e.splits:
      raise ValueError(f'config.eval.splits must name held_out and/or train, got {e.splits}')
    for name, least in (('batch_size', 1), ('plan_chunk', 0), ('key_seed', -1)):
      if name in e and (not isinstance(e[name], int) or e[name] < least):
        raise ValueError(f'config.eval.{name} must be an integer >= {least}, got {e[name]!r}')
    for name in ('action_noise', 'obs_noise'):
      if name in e and not 0.0 <= float(e[name]) < float('inf'):
        raise ValueError(f'config.eval.{name} must be a std >= 0, got {e[name]!r}')
    if 'obs_noise_dims' in e and e.obs_noise_dims not in ('all', 'informative'):
      raise ValueError(f"config.eval.obs_noise_dims must be 'all' or 'informative', "
                       f'got {e.obs_noise_dims!r}')
    if 'obs_noise' in e and e.obs_noise > 0 and ModelSettings.from_config(config).images:
      raise ValueError('config.eval.obs_noise is noise on the state, and image observations are '
                       'rendered without it: set config.eval.obs_noise=0')
  if 'data' in config:
    from ld_mpc_jax.data import sources  # pylint: disable=g-import-not-at-top (environments)
    sources.SOURCES.check(config.data.source)
    if config.data.source == 'tdmpc2' and not config.data.path:
      raise ValueError('config.data.source=tdmpc2 needs config.data.path (chunk file, glob '
                       'pattern or directory)')


def _validate_variant(config: ml_collections.ConfigDict) -> None:
  """Model kinds (their registries) and the planner options each one supports."""
  from ld_mpc_jax.model import dynamics  # pylint: disable=g-import-not-at-top
  m, p = config.model, config.plan
  proposal = proposals.PROPOSALS.get(m.proposal_type)
  dyn = dynamics.DYNAMICS.get(m.dynamics_type)
  if not proposal.sequence and not dyn.one_step:
    raise ValueError(f'config.model.dynamics_type {m.dynamics_type} needs whole action sequences '
                     f'up front, but proposal_type {m.proposal_type!r} proposes one action per '
                     'latent')
  if not dyn.one_step and 'latent_filter' in p and p.latent_filter > 0:
    raise ValueError('config.plan.latent_filter needs a one-step dynamics_type (its one-step '
                     f'prediction), not {m.dynamics_type}')
  if not dyn.one_step and p.num_prior_candidates:
    raise ValueError('config.plan.num_prior_candidates must be 0 with dynamics_type '
                     f'{m.dynamics_type}: actor-prior candidates need a step-by-step rollout')
  if not proposal.sequence and p.warm_start_steps:
    raise ValueError('config.plan.warm_start_steps must be 0 unless the proposal_type proposes '
                     f'sequences (got {m.proposal_type!r}): only sequences can be shifted')
  if p.guidance_scale < 0:
    raise ValueError(f'config.plan.guidance_scale must be >= 0 (0 = off), got {p.guidance_scale}')
  if p.guidance_scale and (not proposal.guidable or config.diffusion.prediction != 'x0'):
    raise ValueError('config.plan.guidance_scale > 0 needs a guidable proposal_type '
                     f"(diffusion_seq, got {m.proposal_type!r}) and diffusion.prediction 'x0'")
  if p.guidance_scale and p.guidance_dynamics_steps < 1:
    raise ValueError('config.plan.guidance_dynamics_steps must be >= 1, '
                     f'got {p.guidance_dynamics_steps}')


def _validate_critic(config: ml_collections.ConfigDict) -> None:
  """config.critic (its kinds' registries) and the planner's robust-selection settings."""
  from ld_mpc_jax.model import actors, dynamics, objective  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.model.critics import TD_TARGETS  # pylint: disable=g-import-not-at-top
  p, o = config.plan, config.critic
  # plan.pessimism < 0 is optimism (mean + |pessimism| std): online.act_pessimism while acting.
  if not isinstance(p.dynamics_draws, int) or p.dynamics_draws < 1:
    raise ValueError(f'config.plan.dynamics_draws must be an integer >= 1, '
                     f'got {p.dynamics_draws!r}')
  objective.VALUES.get(config.critic.value)
  actor = actors.ACTORS.get(config.critic.actor)
  if o.td_target not in TD_TARGETS:
    raise ValueError(f'config.critic.td_target must be one of {TD_TARGETS}, '
                     f'got {o.td_target!r}')
  if actor.value and o.value != actor.value:
    raise ValueError(f'config.critic.actor {o.actor!r} needs the Q ensemble: '
                     f'config.critic.value={actor.value!r}')
  actors.check_log_std_map(o.log_std_map)
  if not 0.0 < o.expectile < 1.0:
    raise ValueError(f'config.critic.expectile must be in (0, 1), got {o.expectile}')
  for name in ('num_values', 'num_q', 'rollout_steps'):
    if not isinstance(o[name], int) or o[name] < 1:
      raise ValueError(f'config.critic.{name} must be an integer >= 1, got {o[name]!r}')
  if o.value_scale <= 0 or o.awr_max_weight <= 0 or o.awr_temperature < 0:
    raise ValueError('config.critic.value_scale and awr_max_weight must be > 0 and '
                     'awr_temperature >= 0')
  if o.latent_rollout and not dynamics.DYNAMICS.get(config.model.dynamics_type).one_step:
    raise ValueError('config.critic.latent_rollout needs one-step dynamics; set it False '
                     f'with dynamics_type {config.model.dynamics_type}')


def online_enabled(config: ml_collections.ConfigDict) -> bool:
  """Whether config asks for online training (`config.online.enabled`, ld_mpc_jax.runs.online)."""
  return 'online' in config and bool(config.online.enabled)


def _validate_online(config: ml_collections.ConfigDict) -> None:
  """config.online (ld_mpc_jax.runs.online), when online training is enabled."""
  if not online_enabled(config):
    return
  if ModelSettings.from_config(config).images:
    raise ValueError('image observations (model.encoder_type=conv, dynamics_type=conv_frames) '
                     'train offline only for now: online acting does not render frames yet')
  o = config.online
  for name, least in (('env_steps', 1), ('num_envs', 1), ('episode_steps', 1),
                      ('checkpoint_every', 1), ('eval_every', 1), ('seed_steps', 0),
                      ('plan_chunk', 0), ('demos', 0), ('demo_pretrain_updates', 0)):
    if not isinstance(o[name], int) or isinstance(o[name], bool) or o[name] < least:
      raise ValueError(f'config.online.{name} must be an integer >= {least}, got {o[name]!r}')
  for name in ('update_ratio', 'action_noise_std', 'prior_noise_std', 'demo_noise_std'):
    if o[name] < 0:
      raise ValueError(f'config.online.{name} must be >= 0, got {o[name]}')
  _validate_demos(config)
  decisions = -(-o.episode_steps // config.eval.action_repeat)
  if decisions < config.horizon + 1:
    raise ValueError(f'config.online.episode_steps ({o.episode_steps}) gives episodes of '
                     f'{decisions} decisions; training windows need horizon + 1 = '
                     f'{config.horizon + 1}')
  if not o.init_from and not o.demos and o.seed_steps < 1:
    raise ValueError('config.online.seed_steps must be >= 1 from scratch (no online.init_from): '
                     'the first updates need seed episodes')
  check_online_budget(config)
  o = config.online
  if o.reward not in ('dense', 'sparse'):
    raise ValueError(f"config.online.reward must be 'dense' or 'sparse', got {o.reward!r}")
  if o.updates_per_call > 1 and config.train.data_parallel:
    raise ValueError('config.online.updates_per_call > 1 is not supported with '
                     'config.train.data_parallel; set one of them off')
  if not isinstance(o.updates_per_call, int) or o.updates_per_call < 1:
    raise ValueError(f'config.online.updates_per_call must be an integer >= 1, '
                     f'got {o.updates_per_call!r}')
  if min(o.exec_noise_start, o.exec_noise_end) < 0:
    raise ValueError('config.online.exec_noise_start and exec_noise_end must be >= 0')
  if o.act_mode not in ACT_MODES:
    raise ValueError(f'config.online.act_mode must be one of {", ".join(map(repr, ACT_MODES))}, '
                     f'got {o.act_mode!r}')
  if o.train_goals not in TRAIN_GOALS:
    raise ValueError(f'config.online.train_goals must be one of '
                     f'{", ".join(map(repr, TRAIN_GOALS))}, got {o.train_goals!r}')
  if o.train_goals == 'random' and not o.init_from and 'train' in config.eval.splits:
    raise ValueError("config.online.train_goals='random' leaves no train goal split (each "
                     "episode draws its own goal): set config.eval.splits=held_out")
  if not 0.0 <= o.exec_noise_corr < 1.0:
    raise ValueError(f'config.online.exec_noise_corr must be in [0, 1), got {o.exec_noise_corr}')
  if o.act_safe_selection and config.plan.num_prior_candidates < 1:
    raise ValueError("config.online.act_safe_selection needs the actor prior's own sequence as a "
                     'candidate: config.plan.num_prior_candidates >= 1')
  _validate_acting_search(config)
  # act_pessimism < 0 is optimism while acting: mean + |act_pessimism| std of the value ensemble
  # (annealed under act_schedule='linear', ld_mpc_jax.model.exploration).


def _validate_acting_search(config: ml_collections.ConfigDict) -> None:
  """The evaluation planner's search (`plan.*`), then the acting one's (`online.act_*`)."""
  o = config.online
  for name in ('act_num_gaussian', 'act_iterations'):
    if not isinstance(o[name], int) or o[name] < 0:
      raise ValueError(f'config.online.{name} must be an integer >= 0, got {o[name]!r}')
  exploration.validate_acting(config)
  try:  # The acting planner's (validate_config checked the evaluation's).
    search.validate_plan(exploration.acting_plan(config), ModelSettings.from_config(config))
  except ValueError as err:
    raise ValueError(f'while acting (config.online.act_num_gaussian, act_iterations): '
                     f'{err}') from None


def _validate_demos(config: ml_collections.ConfigDict) -> None:
  """config.online's demonstration fields (ld_mpc_jax.data.demos)."""
  o = config.online
  for name in ('demo_share_start', 'demo_share_end'):
    if not 0.0 <= o[name] <= 1.0:
      raise ValueError(f'config.online.{name} must be in [0, 1], got {o[name]}')
  if o.demo_path and not o.demos:
    raise ValueError('config.online.demo_path is set but config.online.demos is 0: '
                     'set how many of its episodes to use')
  if o.demo_path and not os.path.isfile(o.demo_path):
    raise ValueError(f'config.online.demo_path={o.demo_path!r} is not a file')


def check_online_budget(config: ml_collections.ConfigDict) -> None:
  """ValueError when config.train.batch_size exceeds the windows of an online run's first update.

  From scratch, the first update samples the seed episodes alone: the random-action waves of
  `online.num_envs` full-length episodes (`online.episode_steps` environment steps,
  ceil(episode_steps / eval.action_repeat) decisions) that start before `online.seed_steps`
  environment steps; each episode of D decisions holds D - horizon windows of horizon + 2
  observations (`runs.window_length`, `data.ReplayBuffer`). No check when no update is ever made,
  nor with `online.init_from`, whose offline dataset `runs.check_config_for_data` checks.
  """
  o, batch = config.online, config.train.batch_size
  if o.init_from or not o.update_ratio or o.demos:  # Sampling from demos has replacement.
    return
  wave = o.num_envs * o.episode_steps  # Environment steps per wave (success ends no episode).
  waves = -(-o.seed_steps // wave)
  if waves * wave >= o.env_steps:  # The run ends before its first update.
    return
  decisions = -(-o.episode_steps // config.eval.action_repeat)
  episodes = waves * o.num_envs
  windows = episodes * max(decisions - config.horizon, 0)
  if batch > windows:
    raise ValueError(
        f'config.train.batch_size ({batch}) is larger than the replay buffer at the first '
        f'update: {windows} windows of {config.horizon + 2} observations in {episodes} seed '
        f'episodes (config.online.seed_steps={o.seed_steps} gives {waves} wave(s) of '
        f'config.online.num_envs={o.num_envs} episodes of config.online.episode_steps='
        f'{o.episode_steps} environment steps, {decisions} decisions at '
        f'config.eval.action_repeat={config.eval.action_repeat}, config.horizon='
        f'{config.horizon}); lower the batch size or raise online.seed_steps')


def _validate_tasks(config: ml_collections.ConfigDict) -> None:
  """Multi-task configs (ld_mpc_jax.model.tasks): every batch splits into equal shares per task."""
  if not tasks.is_multitask(config):
    return
  num = tasks.num_tasks(config)
  if config.train.batch_size % num:
    raise ValueError(f'config.train.batch_size ({config.train.batch_size}) must be a multiple '
                     f'of the number of tasks ({num}): batches hold equal shares per task')
  dim = config.model.task_dim
  if not isinstance(dim, int) or dim < 1:
    raise ValueError(f'config.model.task_dim must be an integer >= 1, got {dim!r}')
  from ld_mpc_jax.data import sources  # pylint: disable=g-import-not-at-top (environments)
  if config.data.source != sources.SCRIPTED:
    raise ValueError('multi-task configs (config.tasks) train on the scripted data: '
                     f'config.data.source must be {sources.SCRIPTED}')
