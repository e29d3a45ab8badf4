"""Typed, frozen settings of the model, its planner and its loss, built once from a config.

The ConfigDict stays the command line's surface and the saved `config.json`; what builds the
networks, `plan` and the loss takes these instead:

  model = ModelSettings.from_config(config)   # sizes, config.model, config.diffusion, critics
  plan = PlanSettings.from_config(config)     # config.plan
  acting = dataclasses.replace(plan, pessimism=0.0)   # a variant, not a cloned config
  losses = LossSettings.from_config(config)   # config.loss, the critics' loss settings

All are frozen and hashable, so a builder cached on them (ops.build_cache.by_settings) traces
once per value in a process. Their defaults and the reasons for them stay in configs/base.py (one
place to read a choice); ld_mpc_jax.plan.search.validate_plan holds the planner's checks,
`ModelSettings.check` the encoder's.
"""

import dataclasses
from typing import Any, Tuple

import ml_collections

_MODEL_FIELDS = (
    'latent_dim', 'encoder_hidden', 'width', 'num_heads', 'mlp_ratio', 'dropout',
    'proposal_blocks', 'dynamics_blocks', 'objective_blocks', 'actor_hidden', 'novelty_members',
    'novelty_target', 'proposal_type', 'dynamics_type', 'normalize_obs', 'obs_mask_constant',
    'task_dim', 'normalize_dynamics', 'encoder_type', 'num_bins', 'vmin', 'vmax', 'image_size',
    'image_channels', 'proprio', 'latent_norm')


# Floats of the robot's own state after the pixels with `model.proprio` (envs.pixels.PROPRIO_INDEX).
PROPRIO_DIM = 8


def _frozen(value: Any) -> Any:
  """Lists (as a config may hold them) as tuples, so that settings hash."""
  return tuple(_frozen(v) for v in value) if isinstance(value, (list, tuple)) else value


class _Hashable:
  """Settings whose list values (from a config, or given to dataclasses.replace) become tuples."""

  def __post_init__(self):
    for field in dataclasses.fields(self):
      object.__setattr__(self, field.name, _frozen(getattr(self, field.name)))


@dataclasses.dataclass(frozen=True)
class ModelSettings(_Hashable):
  """What builds, initialises and applies the networks (ld_mpc_jax.model.models): the sizes,
  `config.model`, `config.diffusion`, the critics' kinds and sizes (`config.critic`) and which
  optional networks exist (`config.loss`'s weights of the progress reward and the exploration
  value). Field names are the config's, within their section."""
  obs_dim: int
  action_dim: int
  horizon: int
  gamma: float
  num_tasks: int  # len(config.tasks) of a multi-task config, else 1 (which task is no setting).
  # config.model
  latent_dim: int
  encoder_hidden: int
  width: int
  num_heads: int
  mlp_ratio: int
  dropout: float
  proposal_blocks: int
  dynamics_blocks: int
  objective_blocks: int
  actor_hidden: Tuple[int, ...]
  novelty_members: int
  novelty_target: str
  proposal_type: str
  dynamics_type: str
  normalize_obs: bool
  obs_mask_constant: bool
  task_dim: int
  normalize_dynamics: bool
  encoder_type: str
  num_bins: int
  vmin: float
  vmax: float
  image_size: int
  image_channels: int
  proprio: bool
  latent_norm: str
  # config.diffusion
  prediction: str
  clip_actions: float
  # config.critic: the kinds, the ensembles' sizes, the value's units
  value: str
  actor: str
  log_std_map: str
  critic_heads: str
  critic_hidden: Tuple[int, ...]
  num_values: int
  num_q: int
  value_scale: float
  # config.loss: whether the learned progress reward and exploration value exist
  progress: bool
  novelty: bool

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'ModelSettings':
    tasks = tuple(config.tasks) if 'tasks' in config and config.tasks else ()
    m, o = config.model, config.critic
    return cls(
        obs_dim=config.obs_dim, action_dim=config.action_dim, horizon=config.horizon,
        gamma=config.gamma, num_tasks=max(len(tasks), 1), **{f: m[f] for f in _MODEL_FIELDS},
        prediction=config.diffusion.prediction, clip_actions=config.diffusion.clip_actions,
        value=o.value, actor=o.actor, log_std_map=o.log_std_map, critic_heads=o.heads,
        critic_hidden=o.hidden, num_values=o.num_values, num_q=o.num_q,
        value_scale=o.value_scale, progress=config.loss.w_progress > 0,
        novelty=config.loss.w_novelty > 0)

  @property
  def images(self) -> bool:
    """Whether the observations are flat images (the `conv` encoder, or `conv_frames`
    dynamics on the images themselves): model.image_size^2 x model.image_channels, 3 channels a
    stacked RGB frame."""
    return self.encoder_type == 'conv' or self.dynamics_type == 'conv_frames'

  @property
  def image_dim(self) -> int:
    """Floats of the pixels in an image observation (the robot's state, with `proprio`, after)."""
    return self.image_size * self.image_size * self.image_channels

  @property
  def proprio_dim(self) -> int:
    """Floats of the robot's state after the pixels (`model.proprio`), else 0."""
    return PROPRIO_DIM if self.proprio else 0

  @property
  def multitask(self) -> bool:
    """Whether the agent is task-conditioned (two or more tasks; ld_mpc_jax.model.tasks)."""
    return self.num_tasks > 1

  def check_sizes(self) -> None:
    """One-line ValueErrors for the transformer's width and heads, the value bins and the
    dropout rate."""
    if self.width % self.num_heads or self.width % 2:
      raise ValueError(f'config.model.width ({self.width}) must be even (Fourier embeddings) and '
                       f'divisible by config.model.num_heads ({self.num_heads})')
    if self.num_bins < 2 or not self.vmin < self.vmax:
      raise ValueError(f'config.model.num_bins must be >= 2 and vmin < vmax, got '
                       f'{self.num_bins}, [{self.vmin}, {self.vmax}]')
    if not 0.0 <= self.dropout < 1.0:
      raise ValueError(f'config.model.dropout must be in [0, 1), got {self.dropout}')

  def check_latent_norm(self, latent_filter: float) -> None:
    """One-line ValueErrors for `model.latent_norm`: 'rms' or 'simnorm' (TD-MPC2's, for the MLP
    encoder and the 'mlp' dynamics, or diffusion dynamics that do not RMS-normalise their
    samples), the latent in whole groups of 8, no filter (it RMS-normalises the latent)."""
    if self.latent_norm not in ('rms', 'simnorm'):
      raise ValueError(f"config.model.latent_norm must be 'rms' or 'simnorm', got "
                       f'{self.latent_norm!r}')
    if self.latent_norm == 'rms':
      return
    if self.encoder_type != 'mlp' or self.latent_dim % 8:
      raise ValueError('config.model.latent_norm=simnorm needs the mlp encoder and a latent_dim '
                       f'in groups of 8, got {self.encoder_type!r} and {self.latent_dim}')
    if (self.dynamics_type != 'mlp' and self.normalize_dynamics) or latent_filter > 0:
      raise ValueError('config.model.latent_norm=simnorm: the dynamics samples and '
                       'plan.latent_filter would be RMS-normalised, off the simplices: use '
                       "dynamics_type='mlp' (or normalize_dynamics=False) and latent_filter=0")

  def check_targets(self) -> None:
    """One-line ValueErrors for the discount and the diffusion's prediction target."""
    if not 0.0 < self.gamma <= 1.0:
      raise ValueError(f'config.gamma must be in (0, 1], got {self.gamma}')
    if self.prediction not in ('x0', 'eps'):
      raise ValueError(f"config.diffusion.prediction must be 'x0' or 'eps', got "
                       f'{self.prediction!r}')

  def check(self, latent_filter: float) -> None:
    """One-line ValueErrors for `model.novelty_target` and `model.encoder_type`: 'mlp'; 'conv'
    (flat images of `model.image_size` >= 39, its VALID convolutions' least, and
    `model.image_channels`, not standardised); or 'identity' (planning in observation space)
    with latent_dim = obs_dim, standardised observations, no sphere for the dynamics (nor
    `plan.latent_filter`). The last two for one task; the 'conv_frames' dynamics need the
    identity encoder on images of an even size (a stride-2 convolution, then upsampling)."""
    if self.novelty_target not in ('latent', 'obs'):
      raise ValueError(f"config.model.novelty_target must be 'latent' or 'obs', got "
                       f'{self.novelty_target!r}')
    kind, frames = self.encoder_type, self.dynamics_type == 'conv_frames'
    image_dim = self.image_dim + self.proprio_dim
    if kind not in ('mlp', 'identity', 'conv'):
      raise ValueError(f"config.model.encoder_type must be 'mlp', 'identity' or 'conv', got "
                       f'{kind!r}')
    if kind != 'mlp' and self.multitask:
      raise ValueError(f'config.model.encoder_type={kind} is for one task (config.tasks is set)')
    if self.images and (self.obs_dim != image_dim or self.image_channels % 3):
      raise ValueError(f'config.obs_dim must be model.image_size^2 x model.image_channels'
                       f'{" + 8 (model.proprio)" if self.proprio else ""} = {image_dim} for '
                       f'image observations, the channels 3 per RGB frame, got '
                       f'{self.obs_dim} and {self.image_channels} channels')
    if self.proprio and kind != 'conv':
      raise ValueError("config.model.proprio (the robot's state beside the pixels) is read by "
                       f"config.model.encoder_type='conv' only, got {kind!r}")
    if frames and (kind != 'identity' or self.image_size % 2):
      raise ValueError("config.model.dynamics_type=conv_frames denoises frames: it needs "
                       "config.model.encoder_type='identity' (the latent is the frame stack) "
                       f'and an even config.model.image_size, got {kind!r} and {self.image_size}')
    if kind == 'conv' and (self.normalize_obs or self.image_size < 39):
      raise ValueError('config.model.encoder_type=conv reads pixels in [0, 255] of images of at '
                       'least 39 x 39: set config.model.normalize_obs=False and '
                       f'config.model.image_size >= 39 (got {self.image_size})')
    if kind != 'identity':
      return
    if self.latent_dim != self.obs_dim:
      raise ValueError(f'config.model.encoder_type=identity: the latent is the observation, so '
                       f'config.model.latent_dim must be config.obs_dim ({self.obs_dim}), got '
                       f'{self.latent_dim}')
    if not self.normalize_obs or self.normalize_dynamics:
      raise ValueError('config.model.encoder_type=identity needs config.model.normalize_obs=True '
                       'and config.model.normalize_dynamics=False (a standardised observation is '
                       "not on the learned encoder's sphere)")
    if self.dynamics_type == 'mlp' or latent_filter > 0:  # Both put z on the sphere.
      raise ValueError('config.model.encoder_type=identity does not go with dynamics_type=mlp '
                       'nor plan.latent_filter > 0: both RMS-normalise the latent, which an '
                       'observation is not')


@dataclasses.dataclass(frozen=True)
class PlanSettings(_Hashable):
  """`config.plan`: how `plan` draws, rolls out, scores and selects candidates (configs/base.py
  gives each field's default and reason). The acting planner's are a `dataclasses.replace` of
  these (ld_mpc_jax.online.settings.OnlineSettings.acting_plan)."""
  num_candidates: int
  action_steps: int
  dynamics_steps: int
  action_eta: float
  dynamics_eta: float
  num_prior_candidates: int
  prior_noise_std: float
  action_noise_std: float
  warm_start_steps: int
  warm_start_t: float
  guidance_scale: float
  guidance_dynamics_steps: int
  pessimism: float
  dynamics_draws: int
  num_gaussian: int
  gaussian_std: float
  first_round: Tuple[str, ...]
  iterations: int
  num_refine: int
  num_elites: int
  temperature: float
  min_std: float
  selection: str
  safe_selection: bool
  safe_margin: float
  safe_margin_scaling: str
  safe_confirm: bool
  confirm_draws: int
  confirm_margin: float
  fallback_drop: float
  fallback_floor: float
  latent_filter: float
  progress_weight: float

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'PlanSettings':
    p = config.plan
    return cls(**{f.name: p[f.name] for f in dataclasses.fields(cls)})

  @property
  def gates(self) -> Tuple[bool, bool]:
    """(confirm, fallback): whether safe selection's confirmation (`safe_confirm`) and its
    fallback to the actor prior (`fallback_drop` > 0) act. Both are gates of safe selection:
    without `safe_selection` they are inert, so that their defaults can be the recommended
    values and `--config.plan.safe_selection=True` alone switches the recommended setting on."""
    return (bool(self.safe_selection and self.safe_confirm),
            bool(self.safe_selection and self.fallback_drop > 0))


_LOSS_FIELDS = ('w_dyn', 'w_act', 'w_rew', 'w_val', 'w_actor', 'w_consistency', 'w_q', 'w_v',
                'w_demo_bc', 'w_noise_inv', 'w_progress', 'w_novelty', 'reward_balance',
                'act_weighting', 'act_target')
# How the proposal's loss weights the data's sequences, and which it denoises (learn.losses).
ACT_WEIGHTINGS = ('uniform', 'advantage')
ACT_TARGETS = ('executed', 'planned')
_CRITIC_LOSS_FIELDS = ('expectile', 'awr_temperature', 'awr_max_weight', 'td_target',
                       'entropy_coef', 'latent_rollout', 'rollout_steps', 'rollout_unroll')


@dataclasses.dataclass(frozen=True)
class LossSettings:
  """What the training loss reads beside the model's settings (ld_mpc_jax.learn.losses): the
  terms' weights (`config.loss`), the critics' and the actor's loss settings (`config.critic`)
  and the observation-noise augmentation (`config.train.obs_noise_aug`)."""
  # config.loss
  w_dyn: float
  w_act: float
  w_rew: float
  w_val: float
  w_actor: float
  w_consistency: float
  w_q: float
  w_v: float
  w_demo_bc: float
  w_noise_inv: float
  w_progress: float
  w_novelty: float
  reward_balance: float
  act_weighting: str
  act_target: str
  # config.critic
  expectile: float
  awr_temperature: float
  awr_max_weight: float
  td_target: str
  entropy_coef: float
  latent_rollout: bool
  rollout_steps: int
  rollout_unroll: bool
  # config.train
  obs_noise_aug: float

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'LossSettings':
    return cls(**{f: config.loss[f] for f in _LOSS_FIELDS},
               **{f: config.critic[f] for f in _CRITIC_LOSS_FIELDS},
               obs_noise_aug=config.train.obs_noise_aug)

  def check_weights(self) -> None:
    """One-line ValueError for the progress reward's weight (ld_mpc_jax.model.progress)."""
    if self.w_progress < 0:
      raise ValueError(f'config.loss.w_progress must be >= 0, got {self.w_progress}')
    if self.act_weighting not in ACT_WEIGHTINGS:
      raise ValueError(f'config.loss.act_weighting must be one of {list(ACT_WEIGHTINGS)}, got '
                       f'{self.act_weighting!r}')
    if self.act_target not in ACT_TARGETS:
      raise ValueError(f'config.loss.act_target must be one of {list(ACT_TARGETS)}, got '
                       f'{self.act_target!r}')

  def check_act_target(self, model: 'ModelSettings') -> None:
    """One-line ValueError for planned targets of a proposal that denoises single actions."""
    if self.act_target == 'planned' and model.proposal_type != 'diffusion_seq':
      raise ValueError("config.loss.act_target='planned' trains a sequence proposal on the "
                       f"planner's sequences: set config.model.proposal_type='diffusion_seq' "
                       f'(got {model.proposal_type!r})')

  def check_batch(self) -> None:
    """One-line ValueErrors for how the loss weights and noises a batch: the reward loss's
    balance of zeros and positives, the observation-noise augmentation."""
    if not 0.0 <= self.reward_balance <= 1.0:
      raise ValueError(f'config.loss.reward_balance must be in [0, 1], got '
                       f'{self.reward_balance!r}')
    if not 0.0 <= self.obs_noise_aug < float('inf'):
      raise ValueError(f'config.train.obs_noise_aug must be a std >= 0, got {self.obs_noise_aug!r}')
