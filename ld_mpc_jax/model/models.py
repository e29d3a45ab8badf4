"""The LD-MPC networks: encoder, action proposal, latent dynamics, sequence objective, actor.

All are plain flax modules. `build_networks(model)` instantiates them from the model's settings
(ld_mpc_jax.model.settings.ModelSettings.from_config(config)); `init_params(config, key)` returns a
dict of their parameters, one entry per network (`init_params_from(model, key)` from the settings).

The proposal and the dynamics come in kinds, one registry entry each: `config.model.
proposal_type` (ld_mpc_jax.model.proposals.PROPOSALS) and `config.model.dynamics_type`
(ld_mpc_jax.model.dynamics.DYNAMICS); the actor's in ld_mpc_jax.model.actors.ACTORS and the terminal
value's in ld_mpc_jax.model.objective.VALUES.
"""

import functools
from typing import NamedTuple, Optional

import flax.linen as nn
import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from ld_mpc_jax.model import actors, dynamics, novelty, objective, progress, proposals, tasks
from ld_mpc_jax.ops import build_cache
from ld_mpc_jax.model.actors import Actor
from ld_mpc_jax.model.config_checks import check_config
from ld_mpc_jax.model.critics import Critics, build_critics
from ld_mpc_jax.model.dynamics import LatentDynamics, MLPDynamics, TrajectoryDynamics  # noqa: F401
from ld_mpc_jax.nets import MLP, Transformer, normalize_latent, position_embedding
from ld_mpc_jax.model.proposals import ActionProposal, MLPProposal  # noqa: F401
from ld_mpc_jax.model.pixels import ConvEncoder
from ld_mpc_jax.model.settings import ModelSettings


class Encoder(nn.Module):
  """MLP encoder o [..., obs_dim] -> z [..., latent_dim] (39 -> 256 -> 512 in the reference).

  With `normalize_obs`, observations are first standardised by the dataset's per-feature mean
  and standard deviation, held as the parameters `obs_mean` and `obs_std` (set once from the
  data by `set_obs_normalization`, never trained: gradients are stopped), so they travel with
  the checkpoint. The output is RMS-normalised: diffusion over z assumes unit-scale data, and a
  fixed norm keeps the jointly trained latent from collapsing to zero. `latent_norm='simnorm'`
  (`model.latent_norm`): TD-MPC2's LayerNorm + SimNorm instead (nets.normalize_latent).
  """
  hidden: int
  latent_dim: int
  normalize_obs: bool = False
  latent_norm: str = 'rms'

  @nn.compact
  def __call__(self, obs: jnp.ndarray) -> jnp.ndarray:
    if self.normalize_obs:
      obs = _standardise(self, obs)
    return normalize_latent(MLP((self.hidden, self.latent_dim), name='mlp')(obs),
                            self.latent_norm)


def _standardise(module: nn.Module, obs: jnp.ndarray) -> jnp.ndarray:
  """obs standardised by `module`'s `obs_mean` and `obs_std` parameters (set from the data by
  `set_obs_normalization`, never trained: gradients stopped)."""
  mean = module.param('obs_mean', nn.initializers.zeros, (obs.shape[-1],))
  std = module.param('obs_std', nn.initializers.ones, (obs.shape[-1],))
  return (obs - jax.lax.stop_gradient(mean)) / jax.lax.stop_gradient(std)


class IdentityEncoder(nn.Module):
  """z = o (`model.encoder_type='identity'`): with `normalize_obs`, the observation standardised
  by the data's statistics as `Encoder` does (the same `obs_mean`/`obs_std` parameters), and
  nothing learned. The latent is then the observation, so the dynamics model predicts the next
  one and the planner searches in observation space (D-MPC's setting)."""
  normalize_obs: bool = False

  @nn.compact
  def __call__(self, obs: jnp.ndarray) -> jnp.ndarray:
    return _standardise(self, obs) if self.normalize_obs else obs


ENCODER_TYPES = ('mlp', 'identity', 'conv')


def build_encoder(m: ModelSettings) -> nn.Module:
  """The encoder `model.encoder_type` names (a config saved before the field migrates to 'mlp');
  'conv' reads flat images (ld_mpc_jax.model.pixels)."""
  if m.encoder_type == 'identity':
    return IdentityEncoder(m.normalize_obs)
  if m.encoder_type == 'conv':
    return ConvEncoder(m.image_size, m.image_channels, m.latent_dim,
                       proprio=m.proprio_dim)
  return Encoder(m.encoder_hidden, m.latent_dim, m.normalize_obs, m.latent_norm)


# Smallest per-feature standard deviation used for normalisation: features that are constant in
# the data (unused object slots) are then only centred, unless they are masked (below).
OBS_STD_FLOOR = 1e-2
# The std given to features constant in the data with `model.obs_mask_constant`: (x - mean) /
# 1e6 is ~0 for any reading a sensor can give, noise included. Finite, so that the optimiser's
# and the EMA's arithmetic on the (never trained) statistics stays finite.
MASKED_OBS_STD = 1e6
# A feature is constant in the data when its std is at most this (float32 round-off of a
# constant column is ~1e-7 of its value).
CONSTANT_OBS_STD = 1e-6


def set_obs_normalization(params: dict, obs: jnp.ndarray, mask_constant: bool = False) -> dict:
  """params with the encoder's obs_mean/obs_std set from observations [N, obs_dim]; with
  `mask_constant`, features constant in `obs` get MASKED_OBS_STD (left out of the input)."""
  if 'obs_mean' not in params['encoder']:
    raise ValueError('the encoder has no observation normalisation (config.model.normalize_obs)')
  obs = jnp.asarray(obs, jnp.float32)
  std = obs.std(0)
  floored = jnp.maximum(std, OBS_STD_FLOOR)
  if mask_constant:
    floored = jnp.where(std <= CONSTANT_OBS_STD, MASKED_OBS_STD, floored)
  encoder = dict(params['encoder'], obs_mean=obs.mean(0), obs_std=floored)
  return dict(params, encoder=encoder)


def informative_dims(params: dict) -> Optional[np.ndarray]:
  """bool [obs_dim]: the observation features that varied in the encoder's training data: those
  not masked; for parameters without masked features (saved before `model.obs_mask_constant`),
  those above the std floor. None without observation normalisation (nothing to tell)."""
  encoder = params['encoder']
  if 'obs_std' not in encoder:
    return None
  std = np.asarray(encoder['obs_std'])
  masked = std >= MASKED_OBS_STD
  return ~masked if masked.any() else std > OBS_STD_FLOOR


class SequenceObjective(nn.Module):
  """Causal transformer over (z_0, a_0, z_1, ..., a_{H-1}, z_H) -> reward and value logits.

  The reward r_i is read at token a_i and the value V_i at token z_i; causal attention makes each
  depend only on the prefix, so V_i is a value of the state reached after i steps.
  """
  width: int
  num_blocks: int
  num_heads: int
  num_bins: int
  mlp_ratio: int = 4
  dropout: float = 0.0

  @nn.compact
  def __call__(self, z: jnp.ndarray, a: jnp.ndarray, deterministic: bool = True):
    """z [..., H+1, D], a [..., H, A] -> (reward logits [..., H, bins], value [..., H+1, bins])."""
    horizon = a.shape[-2]
    if z.shape[-2] != horizon + 1:
      raise ValueError(f'need H+1 latents for H actions, got {z.shape[-2]} and {horizon}')
    zt = nn.Dense(self.width, name='z_proj')(z)
    at = nn.Dense(self.width, name='a_proj')(a)
    # Interleave: [z_0, a_0, z_1, a_1, ..., a_{H-1}, z_H].
    pairs = jnp.stack([zt[..., :-1, :], at], axis=-2)
    pairs = pairs.reshape(pairs.shape[:-3] + (2 * horizon, self.width))
    tokens = jnp.concatenate([pairs, zt[..., -1:, :]], axis=-2)
    tokens = tokens + position_embedding(2 * horizon + 1, self.width)
    mask = nn.make_causal_mask(jnp.ones(tokens.shape[:-1], jnp.int32))
    h = Transformer(self.num_blocks, self.num_heads, self.mlp_ratio, self.dropout,
                    name='backbone')(tokens, mask, deterministic)
    reward_logits = nn.Dense(self.num_bins, name='reward_head')(h[..., 1::2, :])
    value_logits = nn.Dense(self.num_bins, name='value_head')(h[..., 0::2, :])
    return reward_logits, value_logits


class Networks(NamedTuple):
  encoder: Encoder
  proposal: nn.Module  # The module of config.model.proposal_type (ld_mpc_jax.model.proposals).
  dynamics: nn.Module  # The module of config.model.dynamics_type (ld_mpc_jax.model.dynamics).
  objective: SequenceObjective
  actor: Actor
  critics: Optional[Critics] = None  # Expectile V and Q ensembles (ld_mpc_jax.model.critics).
  progress: Optional[nn.Module] = None  # The learned progress reward (ld_mpc_jax.model.progress).
  novelty: Optional[nn.Module] = None  # The learned exploration value (ld_mpc_jax.model.novelty).


def uses_critics(m: ModelSettings) -> bool:
  """Whether the model has Q and V ensembles: its value kind or its actor kind needs them."""
  return objective.get(m).needs_critics or actors.get(m).needs_critics


def build_networks(m: ModelSettings) -> Networks:
  """Instantiates the networks from the model's settings and the kinds' entries (no parameters
  yet)."""
  common = dict(width=m.width, num_heads=m.num_heads, mlp_ratio=m.mlp_ratio, dropout=m.dropout)
  return Networks(
      encoder=build_encoder(m),
      proposal=proposals.get(m).build(m),
      dynamics=dynamics.get(m).build(m),
      objective=SequenceObjective(num_blocks=m.objective_blocks, num_bins=m.num_bins, **common),
      actor=Actor(tuple(m.actor_hidden), m.action_dim, stochastic=actors.get(m).stochastic,
                  log_std_map=m.log_std_map),
      critics=build_critics(m) if uses_critics(m) else None,
      progress=progress.build(m) if m.progress else None,
      novelty=novelty.build(m) if m.novelty else None,
  )


def init_params(config: ml_collections.ConfigDict, key: jax.Array) -> dict:
  """Initial parameters: {'encoder', 'proposal', 'dynamics', 'objective', 'actor'} -> pytree,
  plus 'critics' when the config uses them (`uses_critics`), 'progress' with the learned
  progress reward (`loss.w_progress`), 'novelty' with the learned exploration value
  (`loss.w_novelty`) and 'task' for a multi-task config (ld_mpc_jax.model.tasks).

  One compiled program: initialising operation by operation compiles hundreds of small ones
  (about 16 s against 4 s on a 2-core CPU at smoke size).
  """
  check_config(config)
  return init_params_from(ModelSettings.from_config(config), key)


def init_params_from(m: ModelSettings, key: jax.Array) -> dict:
  """`init_params` from the model's settings (ModelSettings.from_config of a checked config)."""
  return _jitted_init(m)(key)


@build_cache.by_settings  # Traced once per settings value in a process.
def _jitted_init(m: ModelSettings):
  return jax.jit(functools.partial(_init_params, m))


def _init_params(m: ModelSettings, key: jax.Array) -> dict:
  nets = build_networks(m)
  h, d, a = m.horizon, m.latent_dim, m.action_dim
  names = Networks._fields[:5]  # The critics' key is apart, so the others do not depend on it.
  keys = dict(zip(names, jax.random.split(key, len(names))), critics=jax.random.fold_in(key, 1))
  obs = jnp.zeros((1, m.obs_dim))
  z = jnp.zeros((1, d))
  proposal_args = proposals.get(m).init_args(m)
  dynamics_args = dynamics.get(m).init_args(m)
  params = {
      'encoder': nets.encoder.init(keys['encoder'], obs)['params'],
      'proposal': nets.proposal.init(keys['proposal'], *proposal_args)['params'],
      'dynamics': nets.dynamics.init(keys['dynamics'], *dynamics_args)['params'],
      'objective': nets.objective.init(keys['objective'], jnp.zeros((1, h + 1, d)),
                                       jnp.zeros((1, h, a)))['params'],
      'actor': nets.actor.init(keys['actor'], z)['params'],
  }
  if nets.critics is not None:
    params['critics'] = nets.critics.init(keys['critics'], z, jnp.zeros((1, a)))['params']
  if nets.progress is not None:  # Its own key: the other networks' start as without it.
    params['progress'] = nets.progress.init(jax.random.fold_in(key, 3), z)['params']
  if nets.novelty is not None:  # Its own key too.
    params['novelty'] = novelty.init(nets.novelty, jax.random.fold_in(key, 4), d, a)
  return tasks.init_task_params(m, jax.random.fold_in(key, 2), params)


def count_params(params) -> int:
  """Number of scalars in a parameter pytree."""
  return int(sum(x.size for x in jax.tree_util.tree_leaves(params)))


def encode(params: dict, obs: jnp.ndarray) -> jnp.ndarray:
  """Latent of one observation [obs_dim] or a batch [..., obs_dim] -> [..., latent_dim].

  The encoder's sizes are read off its parameters, so no config is needed.
  """
  enc = params['encoder']
  if 'conv_0' in enc:  # model.encoder_type='conv': flat images.
    return _encode_images(enc, jnp.asarray(obs, jnp.float32))
  identity = 'mlp' not in enc  # model.encoder_type='identity': the standardised observation.
  obs_dim = (enc['obs_mean'] if identity else enc['mlp']['dense_0']['kernel']).shape[0]
  obs = jnp.asarray(obs, jnp.float32)
  if obs.ndim == 0 or obs.shape[-1] != obs_dim:
    raise ValueError(f'encode expects observations of shape [..., {obs_dim}], got {obs.shape}')
  if identity:
    return IdentityEncoder(normalize_obs=True).apply({'params': enc}, obs)
  return _apply_encoder(enc, obs)


def _encode_images(enc: dict, obs: jnp.ndarray) -> jnp.ndarray:
  """ConvEncoder's latent of flat images, its image size read off the input and checked against
  the parameters (VALID convolutions: 7 and 5 and 3 with stride 2, then 3). Sizes that the
  convolutions map to the same output (63 to 66 pixels, say) cannot be told apart here."""
  channels = enc['conv_0']['kernel'].shape[2]
  proprio, features = _proprio_shape(enc)
  dim = obs.shape[-1] - proprio if obs.ndim else 0
  size = int(round((max(dim, 0) / channels) ** 0.5))
  out = size
  for kernel, stride in ((7, 2), (5, 2), (3, 2), (3, 1)):
    out = (out - kernel) // stride + 1
  conv_features = enc['out']['kernel'].shape[0] - (features if proprio else 0)
  if size * size * channels != dim or out < 1 or (
      out * out * enc['conv_3']['kernel'].shape[3] != conv_features):
    tail = f' + {proprio} (the robot\'s state)' if proprio else ''
    raise ValueError(f'encode expects flat images [..., S * S * {channels}{tail}] of a size whose '
                     f'convolutions give the encoder\'s {conv_features} features, got {obs.shape}')
  return _apply_conv_encoder(enc, obs, size)


@functools.partial(jax.jit, static_argnums=2)
def _apply_conv_encoder(enc: dict, obs: jnp.ndarray, size: int) -> jnp.ndarray:
  channels, latent = enc['conv_0']['kernel'].shape[2], enc['out']['kernel'].shape[1]
  proprio, features = _proprio_shape(enc)
  return ConvEncoder(size, channels, latent, proprio=proprio,
                     proprio_features=features).apply({'params': enc}, obs)


def _proprio_shape(enc: dict):
  """(floats of the robot's state the encoder reads, width of its layer of them), read off its
  parameters (`model.proprio`); (0, ConvEncoder's default width) without them."""
  if 'proprio' not in enc:
    return 0, ConvEncoder.proprio_features
  return tuple(enc['proprio']['kernel'].shape)


@jax.jit
def _apply_encoder(enc_params: dict, obs: jnp.ndarray) -> jnp.ndarray:
  hidden = enc_params['mlp']['dense_0']['kernel'].shape[1]
  latent = enc_params['mlp']['dense_1']['kernel'].shape[1]
  norm = 'simnorm' if 'latent_norm' in enc_params else 'rms'  # Its LayerNorm's parameters.
  return Encoder(hidden, latent, 'obs_mean' in enc_params, norm).apply({'params': enc_params},
                                                                      obs)
