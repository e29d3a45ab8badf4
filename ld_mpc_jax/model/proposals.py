"""Action proposals, one registry entry per kind (`config.model.proposal_type`).

  'diffusion_seq'   diffusion over the whole H-step action sequence given z_0 (default);
  'diffusion_step'  diffusion over one action given the current latent z_i;
  'mlp'             Gaussian MLP policy over one action given z_i.

An entry carries everything its kind needs: the module (`build`), dummy inputs for `init`
(`init_args`), its training loss (`loss`), its sampler (`make_propose`, and `make_step` for
single-step kinds, drawn inside the planner's rollout), whether it proposes whole sequences
(`sequence`), supports energy guidance (`guidable`), and its input layers that read the latent
(`conditioning`, parameter paths: the multi-task bias of ld_mpc_jax.model.tasks).
"""

from typing import Callable, Optional, Tuple

import flax.linen as nn
import jax
import jax.numpy as jnp

from ld_mpc_jax.ops import diffusion
from ld_mpc_jax.nets import MLP, TimeEmbedding, Transformer, position_embedding
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.ops.registry import Registry

PROPOSALS = Registry('proposal', 'config.model.proposal_type')


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


def transitions(z: jnp.ndarray, action: jnp.ndarray) -> Tuple[jnp.ndarray, jnp.ndarray]:
  """Teacher-forced pairs of a window: z [B, H+2, D], action [B, H+1, A] ->
  (z_i [B (H+1), D], a_i [B (H+1), A]) for all i <= H."""
  n = action.shape[0] * action.shape[1]
  return z[:, :-1].reshape(n, -1), action.reshape(n, -1)


def gaussian_nll(mean: jnp.ndarray, log_std: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
  """Mean over all entries of 0.5 ((a - mean) / std)^2 + log std (the constant dropped)."""
  return jnp.mean(0.5 * ((a - mean) * jnp.exp(-log_std)) ** 2 + log_std)


def _diffusion_propose(m: ModelSettings, plan: PlanSettings, module, horizon: int,
                       guide: Optional[Callable]) -> Callable:
  """propose(params, z [D] or [N, D], key, num, init=None) -> [num, horizon, A] by denoising.

  Cold start: `plan.action_steps` steps from noise at t = 1. Warm start (`init` [H, A] and
  `plan.warm_start_steps` > 0): `init` noised to t = `plan.warm_start_t` per candidate, then
  `warm_start_steps` steps (SDEdit-style). `guide(params, z, key, model_fn) -> model_fn`
  (optional) wraps the denoiser (energy guidance, ld_mpc_jax.plan.planner)."""
  p, a = plan, m.action_dim

  def propose(params, z, key, num, init=None):
    variables = {'params': params['proposal']}
    cond = module.apply(variables, z, method=ActionProposal.embed_cond)  # [..., 1, W]
    if z.ndim == 1:
      cond = jnp.broadcast_to(cond, (num,) + cond.shape)
    model_fn = lambda a_t, t: module.apply(variables, a_t, t, cond,
                                           method=ActionProposal.denoise)
    init_key, sample_key, guide_key = jax.random.split(key, 3)
    if guide is not None:
      model_fn = guide(params, z, guide_key, model_fn)
    noise = jax.random.normal(init_key, (num, horizon, a))
    if init is None or p.warm_start_steps == 0:
      return diffusion.sample(model_fn, noise, sample_key, p.action_steps, p.action_eta,
                              m.prediction, clip_x0=m.clip_actions)
    x_init = diffusion.q_sample(jnp.broadcast_to(init, (num, horizon, a)),
                                jnp.full((num,), p.warm_start_t), noise)
    return diffusion.sample(model_fn, x_init, sample_key, p.warm_start_steps, p.action_eta,
                            m.prediction, clip_x0=m.clip_actions, t_start=p.warm_start_t)

  return propose


class _SingleStep:
  """Shared by single-step kinds: sequences of one action, drawn per latent in the rollout."""
  sequence = False
  guidable = False

  def make_propose(self, m: ModelSettings, plan: PlanSettings, module, guide=None) -> Callable:
    """propose(params, z [D], key, num, init=None) -> [num, 1, A]: one action for z."""
    step = self.make_step(m, plan, module)
    return lambda params, z, key, num, init=None: step(
        params, jnp.broadcast_to(z, (num,) + z.shape), key)[:, None]


class DiffusionSequence:
  """Diffusion over a_{0:H} given z_0; trained by denoising the data's sequences."""
  sequence = True
  guidable = True
  conditioning = (('cond_proj',),)

  def build(self, m: ModelSettings):
    return ActionProposal(m.horizon, m.action_dim, m.width, m.proposal_blocks, m.num_heads,
                          m.mlp_ratio, m.dropout)

  def init_args(self, m: ModelSettings):
    z = jnp.zeros((1, m.latent_dim))
    return jnp.zeros((1, m.horizon, m.action_dim)), jnp.zeros((1,)), z

  def loss(self, m: ModelSettings, module, params, z, action, key, rngs, weights=None):
    """Denoising loss of a_{0:H-1} given z_0: z [B, H+2, D], action [B, H+1, A] -> []; with
    `weights` [B, H+1] (mean 1), each window's by the weight of its first action."""
    h = m.horizon
    fn = lambda a_t, t: module.apply({'params': params['proposal']}, a_t, t, z[:, 0],
                                     deterministic=False, rngs=rngs)
    per_window = diffusion.denoising_loss(fn, action[:, :h], key, m.prediction)
    return per_window.mean() if weights is None else jnp.mean(weights[:, 0] * per_window)

  def make_propose(self, m: ModelSettings, plan: PlanSettings, module, guide=None):
    return _diffusion_propose(m, plan, module, m.horizon, guide)


class DiffusionStep(_SingleStep):
  """Diffusion over one action a_i given z_i."""
  conditioning = (('cond_proj',),)

  def build(self, m: ModelSettings):
    return ActionProposal(1, m.action_dim, m.width, m.proposal_blocks, m.num_heads,
                          m.mlp_ratio, m.dropout)

  def init_args(self, m: ModelSettings):
    z = jnp.zeros((1, m.latent_dim))
    return jnp.zeros((1, 1, m.action_dim)), jnp.zeros((1,)), z

  def loss(self, m: ModelSettings, module, params, z, action, key, rngs, weights=None):
    """Denoising loss of a_i given z_i, all i <= H: z [B, H+2, D], action [B, H+1, A] -> [];
    with `weights` [B, H+1] (mean 1), each pair's by its weight."""
    z_in, a_in = transitions(z, action)
    fn = lambda a_t, t: module.apply({'params': params['proposal']}, a_t, t, z_in,
                                     deterministic=False, rngs=rngs)
    per_pair = diffusion.denoising_loss(fn, a_in[:, None], key, m.prediction)
    return per_pair.mean() if weights is None else jnp.mean(weights.reshape(-1) * per_pair)

  def make_step(self, m: ModelSettings, plan: PlanSettings, module) -> Callable:
    """step(params, zs [N, D], key) -> [N, A] in [-1, 1], `plan.action_steps` steps."""
    p = plan

    def step(params, zs, key):
      variables = {'params': params['proposal']}
      init_key, sample_key = jax.random.split(key)
      noise = jax.random.normal(init_key, zs.shape[:-1] + (1, m.action_dim))
      cond = module.apply(variables, zs, method=ActionProposal.embed_cond)  # [N, 1, W]
      model_fn = lambda a_t, t: module.apply(variables, a_t, t, cond,
                                             method=ActionProposal.denoise)
      a = diffusion.sample(model_fn, noise, sample_key, p.action_steps, p.action_eta,
                           m.prediction, clip_x0=m.clip_actions)
      return jnp.clip(a[..., 0, :], -1.0, 1.0)

    return step


class GaussianMLP(_SingleStep):
  """Gaussian MLP policy over a_i given z_i; trained by negative log-likelihood."""
  conditioning = (('mlp', 'dense_0'),)

  def build(self, m: ModelSettings):
    return MLPProposal(tuple(m.actor_hidden), m.action_dim)

  def init_args(self, m: ModelSettings):
    return (jnp.zeros((1, m.latent_dim)),)

  def loss(self, m: ModelSettings, module, params, z, action, key, rngs, weights=None):
    """Gaussian NLL per dimension of a_i given z_i, all i <= H -> []; with `weights` [B, H+1]
    (mean 1), each pair's by its weight."""
    z_in, a_in = transitions(z, action)
    mean, log_std = module.apply({'params': params['proposal']}, z_in)
    if weights is None:
      return gaussian_nll(mean, log_std, a_in)
    nll = jnp.mean(0.5 * ((a_in - mean) * jnp.exp(-log_std)) ** 2 + log_std, axis=-1)
    return jnp.mean(weights.reshape(-1) * nll)

  def make_step(self, m: ModelSettings, plan: PlanSettings, module) -> Callable:
    """step(params, zs [N, D], key) -> [N, A]: mean + std noise, clipped to [-1, 1]."""
    def step(params, zs, key):
      init_key, _ = jax.random.split(key)
      noise = jax.random.normal(init_key, zs.shape[:-1] + (1, m.action_dim))
      mean, log_std = module.apply({'params': params['proposal']}, zs)
      return jnp.clip(mean + jnp.exp(log_std) * noise[..., 0, :], -1.0, 1.0)

    return step


PROPOSALS.register('diffusion_seq', DiffusionSequence())
PROPOSALS.register('diffusion_step', DiffusionStep())
PROPOSALS.register('mlp', GaussianMLP())


def get(m: ModelSettings):
  """The entry of `model.proposal_type` (ValueError naming the kinds if unknown)."""
  return PROPOSALS.get(m.proposal_type)
