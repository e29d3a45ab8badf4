"""Latent dynamics, one registry entry per kind (`config.model.dynamics_type`).

  'diffusion_ar'    diffusion over z_{i+1} given (z_i, a_i), autoregressive (default);
  'diffusion_traj'  diffusion over the whole latent trajectory z_{1:H} given (z_0, a_{0:H});
  'mlp'             deterministic MLP z_{i+1} = f(z_i, a_i);
  'conv_frames'     diffusion over the next frame stack, a small convolutional denoiser (the
                    pixel-space baseline, with the identity encoder; ld_mpc_jax.model.pixels).

An entry carries everything its kind needs: the module (`build`), dummy inputs for `init`
(`init_args`), its training loss (`loss`), how the planner rolls it out (`one_step` kinds give
`make_step`, a transition the planner scans over the horizon; the others give `make_rollout`,
all H latents at once), and its input layers that read the latent (`conditioning`, parameter
paths: the multi-task bias of ld_mpc_jax.model.tasks).
"""

from typing import Callable

import flax.linen as nn
import jax
import jax.numpy as jnp
from ld_mpc_jax.ops import diffusion
from ld_mpc_jax.nets import (MLP, TimeEmbedding, Transformer, normalize_latent,
                             position_embedding)
from ld_mpc_jax.ops.numerics import rms_normalize
from ld_mpc_jax.model.pixels import FrameDynamics
from ld_mpc_jax.model.proposals import transitions
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.ops.registry import Registry

DYNAMICS = Registry('dynamics', 'config.model.dynamics_type')


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
  """Deterministic transition z_{i+1} = normalise(MLP([z_i, a_i])), on the encoder's manifold:
  its sphere (`latent_norm='rms'`) or TD-MPC2's simplices (LayerNorm + SimNorm, 'simnorm')."""
  hidden: int
  latent_dim: int
  latent_norm: str = 'rms'

  @nn.compact
  def __call__(self, z: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """z [..., D], a [..., A] -> [..., D]."""
    x = jnp.concatenate([z, a], axis=-1)
    h = MLP((self.hidden, self.hidden, self.latent_dim), name='mlp')(x)
    return normalize_latent(h, self.latent_norm)


def _maybe_normalize(m: ModelSettings) -> Callable:
  """rms_normalize with `model.normalize_dynamics` (samples on the encoder's sphere), else id."""
  return rms_normalize if m.normalize_dynamics else (lambda x: x)


def _transformer_args(m: ModelSettings) -> dict:
  return dict(width=m.width, num_blocks=m.dynamics_blocks, num_heads=m.num_heads,
              mlp_ratio=m.mlp_ratio, dropout=m.dropout)


class DiffusionAR:
  """Diffusion over z_{i+1} given (z_i, a_i); trained teacher-forced on all H + 1 transitions,
  sampled in `steps` denoising steps per transition."""
  one_step = True
  conditioning = (('z_proj',),)

  def build(self, m: ModelSettings):
    return LatentDynamics(m.latent_dim, **_transformer_args(m))

  def init_args(self, m: ModelSettings):
    z = jnp.zeros((1, m.latent_dim))
    return z, jnp.zeros((1,)), z, jnp.zeros((1, m.action_dim))

  def loss(self, m: ModelSettings, module, params, z, action, key, rngs):
    """Denoising loss of sg(z_{i+1}) given (z_i, a_i), i <= H: z [B, H+2, D] -> []."""
    z_in, a_in = transitions(z, action)
    z_next = jax.lax.stop_gradient(z[:, 1:]).reshape(z_in.shape)
    fn = lambda x_t, t: module.apply({'params': params['dynamics']}, x_t, t, z_in, a_in,
                                     deterministic=False, rngs=rngs)
    return diffusion.denoising_loss(fn, z_next, key, m.prediction).mean()

  def make_step(self, m: ModelSettings, module, steps: int, eta: float) -> Callable:
    """step(params, z [N, D], a [N, A], key) -> z_next [N, D]."""
    normalize, prediction = _maybe_normalize(m), m.prediction

    def step(params, z_cur, a_cur, key):
      dyn_vars = {'params': params['dynamics']}
      cond = module.apply(dyn_vars, z_cur, a_cur, method=LatentDynamics.embed_cond)
      model_fn = lambda x_t, t: module.apply(dyn_vars, x_t, t, cond,
                                             method=LatentDynamics.denoise)
      x_init = jax.random.normal(jax.random.fold_in(key, 0), z_cur.shape)
      return normalize(diffusion.sample(model_fn, x_init, jax.random.fold_in(key, 1), steps,
                                        eta, prediction))

    return step


class DiffusionTrajectory:
  """Diffusion over z_{1:H} given (z_0, a_{0:H-1}): needs whole action sequences up front."""
  one_step = False
  conditioning = (('z_proj',),)

  def build(self, m: ModelSettings):
    return TrajectoryDynamics(m.latent_dim, **_transformer_args(m))

  def init_args(self, m: ModelSettings):
    h, d, a = m.horizon, m.latent_dim, m.action_dim
    return jnp.zeros((1, h, d)), jnp.zeros((1,)), jnp.zeros((1, d)), jnp.zeros((1, h, a))

  def loss(self, m: ModelSettings, module, params, z, action, key, rngs):
    """Denoising loss of sg(z_{1:H}) given z_0 and a_{0:H-1}, as the planner uses it -> []."""
    h = m.horizon
    target = jax.lax.stop_gradient(z[:, 1:h + 1])
    fn = lambda x_t, t: module.apply({'params': params['dynamics']}, x_t, t, z[:, 0],
                                     action[:, :h], deterministic=False, rngs=rngs)
    return diffusion.denoising_loss(fn, target, key, m.prediction).mean()

  def make_rollout(self, m: ModelSettings, plan: PlanSettings, module) -> Callable:
    """roll(params, z [D], actions [K, H, A], key) -> latents [K, H+1, D] (latents[:, 0] = z),
    `plan.dynamics_steps` denoising steps for all H latents at once."""
    p, h = plan, m.horizon
    normalize, prediction = _maybe_normalize(m), m.prediction

    def roll(params, z, actions, key):
      dyn_vars = {'params': params['dynamics']}
      k = actions.shape[0]
      cond = module.apply(dyn_vars, jnp.broadcast_to(z, (k,) + z.shape), actions,
                          method=TrajectoryDynamics.embed_cond)
      model_fn = lambda x_t, t: module.apply(dyn_vars, x_t, t, cond,
                                             method=TrajectoryDynamics.denoise)
      x_init = jax.random.normal(jax.random.fold_in(key, 0), (k, h) + z.shape)
      zs = normalize(diffusion.sample(model_fn, x_init, jax.random.fold_in(key, 1),
                                      p.dynamics_steps, p.dynamics_eta, prediction))
      return jnp.concatenate([jnp.broadcast_to(z, (k, 1) + z.shape), zs], axis=1)

    return roll


class DeterministicMLP:
  """z_{i+1} = MLP(z_i, a_i); trained by MSE on all H + 1 transitions."""
  one_step = True
  conditioning = (('mlp', 'dense_0'),)

  def build(self, m: ModelSettings):
    return MLPDynamics(m.width, m.latent_dim, m.latent_norm)

  def init_args(self, m: ModelSettings):
    return jnp.zeros((1, m.latent_dim)), jnp.zeros((1, m.action_dim))

  def loss(self, m: ModelSettings, module, params, z, action, key, rngs):
    """MSE of the prediction of sg(z_{i+1}) from (z_i, a_i), i <= H -> []."""
    z_in, a_in = transitions(z, action)
    z_next = jax.lax.stop_gradient(z[:, 1:]).reshape(z_in.shape)
    z_pred = module.apply({'params': params['dynamics']}, z_in, a_in)
    return jnp.mean((z_pred - z_next) ** 2)

  def make_step(self, m: ModelSettings, module, steps: int, eta: float) -> Callable:
    return lambda params, z_cur, a_cur, key: module.apply({'params': params['dynamics']},
                                                           z_cur, a_cur)


class ConvFrames(DiffusionAR):
  """Diffusion over the next frame stack given (frames, action), autoregressive like
  'diffusion_ar' (its loss and dummy inputs); needs the identity encoder (the latent is the
  frame stack)."""
  conditioning = ()  # One task only (config checks).

  def build(self, m: ModelSettings):
    return FrameDynamics(m.image_size, m.image_channels)

  def make_step(self, m: ModelSettings, module, steps: int, eta: float) -> Callable:
    """step(params, z [N, D], a [N, A], key) -> z_next [N, D]."""
    def step(params, z_cur, a_cur, key):
      model_fn = lambda x_t, t: module.apply({'params': params['dynamics']}, x_t, t, z_cur,
                                             a_cur)
      x_init = jax.random.normal(jax.random.fold_in(key, 0), z_cur.shape)
      return diffusion.sample(model_fn, x_init, jax.random.fold_in(key, 1), steps, eta,
                              m.prediction)
    return step


DYNAMICS.register('diffusion_ar', DiffusionAR())
DYNAMICS.register('diffusion_traj', DiffusionTrajectory())
DYNAMICS.register('mlp', DeterministicMLP())
DYNAMICS.register('conv_frames', ConvFrames())


def get(m: ModelSettings):
  """The entry of `model.dynamics_type` (ValueError naming the kinds if unknown)."""
  return DYNAMICS.get(m.dynamics_type)


def make_transition(m: ModelSettings, module: nn.Module, steps: int, eta: float) -> Callable:
  """One-step kinds: step(params, z [N, D], a [N, A], key) -> z_next [N, D], sampled in `steps`
  denoising steps with `eta` (the planner's: `plan.dynamics_steps` and `plan.dynamics_eta`)."""
  return get(m).make_step(m, module, steps, eta)
