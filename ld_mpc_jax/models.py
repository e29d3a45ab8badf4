"""The LD-MPC networks: encoder, action proposal, latent dynamics, sequence objective, actor.

All are plain flax modules. `build_networks(config)` instantiates them from a config;
`init_params(config, key)` returns a dict of their parameters, one entry per network.

The proposal and the dynamics each come in three kinds, chosen by `config.model.proposal_type`
and `config.model.dynamics_type` (the ablations of experiments/ablations.py):
  proposal  'diffusion_seq'  diffusion over the whole H-step action sequence given z_0 (default);
            'diffusion_step' diffusion over one action given the current latent z_i;
            'mlp'            Gaussian MLP policy over one action given z_i;
  dynamics  'diffusion_ar'   diffusion over z_{i+1} given (z_i, a_i), autoregressive (default);
            'diffusion_traj' diffusion over the whole latent trajectory z_{1:H} given (z_0, a_{0:H});
            'mlp'            deterministic MLP z_{i+1} = f(z_i, a_i).
Single-step proposals are sampled inside the rollout, one action per visited latent.
"""

import functools
from typing import NamedTuple, Optional

import flax.linen as nn
import jax
import jax.numpy as jnp
import ml_collections

from ld_mpc_jax import diffusion, tasks
from ld_mpc_jax.config_checks import validate_config
from ld_mpc_jax.critics import Critics, build_critics, objective_settings
from ld_mpc_jax.networks import MLP, TimeEmbedding, Transformer, position_embedding


def rms_normalize(x: jnp.ndarray, eps: float = 1e-6) -> jnp.ndarray:
  """Scales each vector to unit root-mean-square: the latent then matches N(0, I)'s scale."""
  return x * jax.lax.rsqrt(jnp.mean(x ** 2, axis=-1, keepdims=True) + eps)


class Encoder(nn.Module):
  """MLP encoder o [..., obs_dim] -> z [..., latent_dim] (39 -> 256 -> 512 in the reference).

  With `normalize_obs`, observations are first standardised by the dataset's per-feature mean
  and standard deviation, held as the parameters `obs_mean` and `obs_std` (set once from the
  data by `set_obs_normalization`, never trained: gradients are stopped), so they travel with
  the checkpoint. The output is RMS-normalised: diffusion over z assumes unit-scale data, and a
  fixed norm keeps the jointly trained latent from collapsing to zero.
  """
  hidden: int
  latent_dim: int
  normalize_obs: bool = False

  @nn.compact
  def __call__(self, obs: jnp.ndarray) -> jnp.ndarray:
    if self.normalize_obs:
      mean = self.param('obs_mean', nn.initializers.zeros, (obs.shape[-1],))
      std = self.param('obs_std', nn.initializers.ones, (obs.shape[-1],))
      obs = (obs - jax.lax.stop_gradient(mean)) / jax.lax.stop_gradient(std)
    return rms_normalize(MLP((self.hidden, self.latent_dim), name='mlp')(obs))


# Smallest per-feature standard deviation used for normalisation: features that are constant in
# the data (unused object slots) are then only centred.
OBS_STD_FLOOR = 1e-2


def set_obs_normalization(params: dict, obs: jnp.ndarray) -> dict:
  """params with the encoder's obs_mean/obs_std set from observations [N, obs_dim]."""
  if 'obs_mean' not in params['encoder']:
    raise ValueError('the encoder has no observation normalisation (config.model.normalize_obs)')
  obs = jnp.asarray(obs, jnp.float32)
  encoder = dict(params['encoder'], obs_mean=obs.mean(0),
                 obs_std=jnp.maximum(obs.std(0), OBS_STD_FLOOR))
  return dict(params, encoder=encoder)


class ActionProposal(nn.Module):
  """Diffusion transformer over an action sequence, conditioned on the latent state.

  Tokens: [z, a_0, ..., a_{H-1}] with Fourier position embeddings; the Fourier embedding of the
  diffusion time is added to every token. Predicts x0 (or eps) for the H action tokens.
  """
  horizon: int
  action_dim: int
  width: int
  num_blocks: int
  num_heads: int
  mlp_ratio: int = 4
  dropout: float = 0.0

  def setup(self):
    self.cond_proj = nn.Dense(self.width)
    self.action_proj = nn.Dense(self.width)
    self.time_embed = TimeEmbedding(self.width)
    self.backbone = Transformer(self.num_blocks, self.num_heads, self.mlp_ratio, self.dropout)
    self.out = nn.Dense(self.action_dim)

  def embed_cond(self, z: jnp.ndarray) -> jnp.ndarray:
    """z [..., D] -> conditioning token [..., 1, W]; computed once per plan, not per step."""
    return self.cond_proj(z)[..., None, :]

  def denoise(self, a_t: jnp.ndarray, t: jnp.ndarray, cond: jnp.ndarray,
              deterministic: bool = True) -> jnp.ndarray:
    """a_t [..., H, A], t [] or [...], cond [..., 1, W] -> prediction [..., H, A]."""
    temb = self.time_embed(t)[..., None, :]
    pos = position_embedding(self.horizon + 1, self.width)
    tokens = jnp.concatenate([cond, self.action_proj(a_t)], axis=-2) + pos + temb
    h = self.backbone(tokens, deterministic=deterministic, outputs=slice(1, None))
    return self.out(h)

  def __call__(self, a_t, t, z, deterministic: bool = True):
    return self.denoise(a_t, t, self.embed_cond(z), deterministic)


class LatentDynamics(nn.Module):
  """Diffusion transformer for one transition p(z_{t+1} | z_t, a_t).

  Tokens: [z_t, a_t, noisy z_{t+1}] with Fourier position embeddings plus the diffusion-time
  embedding; the prediction of z_{t+1} is read from the last token. Applied autoregressively over
  the horizon by the planner.
  """
  latent_dim: int
  width: int
  num_blocks: int
  num_heads: int
  mlp_ratio: int = 4
  dropout: float = 0.0

  def setup(self):
    self.z_proj = nn.Dense(self.width)
    self.a_proj = nn.Dense(self.width)
    self.x_proj = nn.Dense(self.width)
    self.time_embed = TimeEmbedding(self.width)
    self.backbone = Transformer(self.num_blocks, self.num_heads, self.mlp_ratio, self.dropout)
    self.out = nn.Dense(self.latent_dim)

  def embed_cond(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """z [..., D], a [..., A] -> conditioning tokens [..., 2, W]; once per transition."""
    return jnp.stack([self.z_proj(z), self.a_proj(a)], axis=-2)

  def denoise(self, x_t: jnp.ndarray, t: jnp.ndarray, cond: jnp.ndarray,
              deterministic: bool = True) -> jnp.ndarray:
    """x_t [..., D] noisy next latent, t [] or [...], cond [..., 2, W] -> prediction [..., D]."""
    temb = self.time_embed(t)[..., None, :]
    pos = position_embedding(3, self.width)
    tokens = jnp.concatenate([cond, self.x_proj(x_t)[..., None, :]], axis=-2) + pos + temb
    h = self.backbone(tokens, deterministic=deterministic, outputs=slice(2, None))
    return self.out(h[..., 0, :])

  def __call__(self, x_t, t, z, a, deterministic: bool = True):
    return self.denoise(x_t, t, self.embed_cond(z, a), deterministic)


class TrajectoryDynamics(LatentDynamics):
  """Diffusion transformer over a whole latent trajectory p(z_{1:H} | z_0, a_{0:H-1}).

  Tokens: [z_0, a_0 + noisy z_1, ..., a_{H-1} + noisy z_H] (bidirectional attention) with Fourier
  position embeddings plus the diffusion-time embedding; predicts the H latents at once. Same
  layers as LatentDynamics; only the tokens differ.
  """

  def embed_cond(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """z [..., D], a [..., H, A] -> conditioning [..., H + 1, W] (z_0 token, then a_i)."""
    return jnp.concatenate([self.z_proj(z)[..., None, :], self.a_proj(a)], axis=-2)

  def denoise(self, x_t: jnp.ndarray, t: jnp.ndarray, cond: jnp.ndarray,
              deterministic: bool = True) -> jnp.ndarray:
    """x_t [..., H, D] noisy z_{1:H}, t [] or [...], cond [..., H+1, W] -> [..., H, D]."""
    horizon = x_t.shape[-2]
    temb = self.time_embed(t)[..., None, :]
    pos = position_embedding(horizon + 1, self.width)
    x = jnp.concatenate([jnp.zeros_like(cond[..., :1, :]), self.x_proj(x_t)], axis=-2)
    h = self.backbone(cond + x + pos + temb, deterministic=deterministic,
                      outputs=slice(1, None))
    return self.out(h)


class MLPDynamics(nn.Module):
  """Deterministic transition z_{i+1} = normalise(MLP([z_i, a_i])), on the encoder's sphere."""
  hidden: int
  latent_dim: int

  @nn.compact
  def __call__(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """z [..., D], a [..., A] -> [..., D]."""
    x = jnp.concatenate([z, a], axis=-1)
    return rms_normalize(MLP((self.hidden, self.hidden, self.latent_dim), name='mlp')(x))


class MLPProposal(nn.Module):
  """Gaussian policy over one action: mean and log-std from an MLP of z (a single-step proposal)."""
  hidden: tuple
  action_dim: int
  log_std_min: float = -5.0
  log_std_max: float = 1.0

  @nn.compact
  def __call__(self, z: jnp.ndarray):
    """z [..., D] -> (mean [..., A], log_std [..., A])."""
    out = MLP(tuple(self.hidden) + (2 * self.action_dim,), name='mlp')(z)
    mean, log_std = jnp.split(out, 2, axis=-1)
    log_std = self.log_std_min + (self.log_std_max - self.log_std_min) * jax.nn.sigmoid(log_std)
    return jnp.tanh(mean), log_std


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


class Actor(nn.Module):
  """Policy prior a = tanh(MLP(z)) in [-1, 1]^A.

  `stochastic`: the MLP also outputs a log-std, and `sample` draws the tanh-squashed Gaussian
  policy of SAC / TD-MPC2 (log-std in [-10, 2], TD-MPC2's bounds); calling the module gives its
  mode tanh(mean), which the planner and the actor-alone policy use.
  """
  hidden: tuple
  action_dim: int
  stochastic: bool = False

  def setup(self):
    out = self.action_dim * (2 if self.stochastic else 1)
    self.mlp = MLP(tuple(self.hidden) + (out,))

  def __call__(self, z: jnp.ndarray) -> jnp.ndarray:
    return jnp.tanh(self.mlp(z)[..., :self.action_dim])

  def sample(self, z: jnp.ndarray, key: jax.Array):
    """z [..., D] -> (a [..., A] in (-1, 1), log pi(a|z) [...]), reparameterised."""
    out = self.mlp(z)
    mean, log_std = out[..., :self.action_dim], jnp.clip(out[..., self.action_dim:], -10., 2.)
    eps = jax.random.normal(key, mean.shape)
    u = mean + jnp.exp(log_std) * eps
    a = jnp.tanh(u)
    log_prob = jnp.sum(-0.5 * eps ** 2 - log_std - 0.5 * jnp.log(2 * jnp.pi)
                       - jnp.log(1.0 - a ** 2 + 1e-6), axis=-1)
    return a, log_prob


PROPOSAL_TYPES = ('diffusion_seq', 'diffusion_step', 'mlp')
DYNAMICS_TYPES = ('diffusion_ar', 'diffusion_traj', 'mlp')


def proposal_type(config: ml_collections.ConfigDict) -> str:
  """config.model.proposal_type; configs saved before the field existed mean the default."""
  return config.model.get('proposal_type', 'diffusion_seq')


def dynamics_type(config: ml_collections.ConfigDict) -> str:
  """config.model.dynamics_type; configs saved before the field existed mean the default."""
  return config.model.get('dynamics_type', 'diffusion_ar')


class Networks(NamedTuple):
  encoder: Encoder
  proposal: nn.Module  # ActionProposal, or MLPProposal for proposal_type 'mlp'.
  dynamics: nn.Module  # LatentDynamics, TrajectoryDynamics or MLPDynamics.
  objective: SequenceObjective
  actor: Actor
  critics: Optional[Critics] = None  # Expectile V and Q ensembles (ld_mpc_jax.critics).


def build_networks(config: ml_collections.ConfigDict) -> Networks:
  """Instantiates the five networks from `config.model` (no parameters yet)."""
  m = config.model
  common = dict(width=m.width, num_heads=m.num_heads, mlp_ratio=m.mlp_ratio, dropout=m.dropout)
  proposal = {
      'diffusion_seq': lambda: ActionProposal(config.horizon, config.action_dim,
                                              num_blocks=m.proposal_blocks, **common),
      'diffusion_step': lambda: ActionProposal(1, config.action_dim,
                                               num_blocks=m.proposal_blocks, **common),
      'mlp': lambda: MLPProposal(tuple(m.actor_hidden), config.action_dim),
  }[proposal_type(config)]()
  dynamics = {
      'diffusion_ar': lambda: LatentDynamics(m.latent_dim, num_blocks=m.dynamics_blocks,
                                             **common),
      'diffusion_traj': lambda: TrajectoryDynamics(m.latent_dim, num_blocks=m.dynamics_blocks,
                                                   **common),
      'mlp': lambda: MLPDynamics(m.width, m.latent_dim),
  }[dynamics_type(config)]()
  return Networks(
      encoder=Encoder(m.encoder_hidden, m.latent_dim, m.get('normalize_obs', False)),
      proposal=proposal,
      dynamics=dynamics,
      objective=SequenceObjective(num_blocks=m.objective_blocks, num_bins=m.num_bins, **common),
      actor=Actor(tuple(m.actor_hidden), config.action_dim,
                  stochastic=objective_settings(config).actor == 'maxq'),
      critics=build_critics(config),
  )


def normalizes_dynamics(config: ml_collections.ConfigDict) -> bool:
  """config.model.normalize_dynamics (False for configs saved before it existed)."""
  return config.model.get('normalize_dynamics', False)


def make_transition(config: ml_collections.ConfigDict, nets: Networks,
                    steps: Optional[int] = None, eta: Optional[float] = None):
  """One-step dynamics kinds: returns step(params, z [N, D], a [N, A], key) -> z_next [N, D].

  Diffusion dynamics sample z_next in `steps` denoising steps with `eta` (default: the
  planner's `plan.dynamics_steps` and `plan.dynamics_eta`). With `model.normalize_dynamics`
  the sample is RMS-normalised like the encoder's output, so that the objective scores
  latents on the manifold it was trained on.
  """
  p, d = config.plan, config.diffusion
  steps = p.dynamics_steps if steps is None else steps
  eta = p.dynamics_eta if eta is None else eta
  normalize = rms_normalize if normalizes_dynamics(config) else (lambda x: x)

  def step(params, z_cur, a_cur, key):
    dyn_vars = {'params': params['dynamics']}
    if dynamics_type(config) == 'mlp':
      return nets.dynamics.apply(dyn_vars, z_cur, a_cur)
    cond = nets.dynamics.apply(dyn_vars, z_cur, a_cur, method=LatentDynamics.embed_cond)
    model_fn = lambda x_t, t: nets.dynamics.apply(dyn_vars, x_t, t, cond,
                                                  method=LatentDynamics.denoise)
    x_init = jax.random.normal(jax.random.fold_in(key, 0), z_cur.shape)
    return normalize(diffusion.sample(model_fn, x_init, jax.random.fold_in(key, 1), steps, eta,
                                      d.prediction))

  return step


def init_params(config: ml_collections.ConfigDict, key: jax.Array) -> dict:
  """Initial parameters: {'encoder', 'proposal', 'dynamics', 'objective', 'actor'} -> pytree,
  plus 'critics' when the config uses them (ld_mpc_jax.critics.uses_critics) and 'task' for a
  multi-task config (ld_mpc_jax.tasks).

  One compiled program: initialising operation by operation compiles hundreds of small ones
  (about 16 s against 4 s on a 2-core CPU at smoke size).
  """
  validate_config(config)
  return jax.jit(functools.partial(_init_params, config))(key)


def _init_params(config: ml_collections.ConfigDict, key: jax.Array) -> dict:
  nets = build_networks(config)
  h, d, a = config.horizon, config.model.latent_dim, config.action_dim
  names = Networks._fields[:5]  # The critics' key is apart, so the others do not depend on it.
  keys = dict(zip(names, jax.random.split(key, len(names))), critics=jax.random.fold_in(key, 1))
  obs = jnp.zeros((1, config.obs_dim))
  z, t = jnp.zeros((1, d)), jnp.zeros((1,))
  proposal_args = {
      'diffusion_seq': (jnp.zeros((1, h, a)), t, z),
      'diffusion_step': (jnp.zeros((1, 1, a)), t, z),
      'mlp': (z,),
  }[proposal_type(config)]
  dynamics_args = {
      'diffusion_ar': (z, t, z, jnp.zeros((1, a))),
      'diffusion_traj': (jnp.zeros((1, h, d)), t, z, jnp.zeros((1, h, a))),
      'mlp': (z, jnp.zeros((1, a))),
  }[dynamics_type(config)]
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
  return tasks.init_task_params(config, jax.random.fold_in(key, 2), params)


def count_params(params) -> int:
  """Number of scalars in a parameter pytree."""
  return int(sum(x.size for x in jax.tree_util.tree_leaves(params)))


def encode(params: dict, obs: jnp.ndarray) -> jnp.ndarray:
  """Latent of one observation [obs_dim] or a batch [..., obs_dim] -> [..., latent_dim].

  The encoder's sizes are read off its parameters, so no config is needed.
  """
  obs_dim = params['encoder']['mlp']['dense_0']['kernel'].shape[0]
  obs = jnp.asarray(obs, jnp.float32)
  if obs.ndim == 0 or obs.shape[-1] != obs_dim:
    raise ValueError(f'encode expects observations of shape [..., {obs_dim}], got {obs.shape}')
  return _apply_encoder(params['encoder'], obs)


@jax.jit
def _apply_encoder(enc_params: dict, obs: jnp.ndarray) -> jnp.ndarray:
  hidden = enc_params['mlp']['dense_0']['kernel'].shape[1]
  latent = enc_params['mlp']['dense_1']['kernel'].shape[1]
  return Encoder(hidden, latent, 'obs_mean' in enc_params).apply({'params': enc_params}, obs)
