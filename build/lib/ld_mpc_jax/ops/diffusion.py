"""Gaussian diffusion in continuous time: cosine schedule, forward noising, loss, samplers.

Time t is continuous in [0, 1] (t = 0 is data, t = 1 is noise), so a model trained once can be
sampled on any grid: DDPM ancestral sampling on the full grid and DDIM on a coarser one are the
same generalised-DDIM update with eta = 1 and eta = 0 (Song et al. 2021, eq. 12).

Models are called as `model_fn(x_t, t) -> prediction` where the prediction is either the clean
sample x0 or the noise eps (`prediction='x0' | 'eps'`).
"""

import math
from typing import Callable

import jax
import jax.numpy as jnp

# alpha_bar is kept in [ALPHA_BAR_MIN, 1] so that eps -> x0 conversion stays finite at t = 1.
ALPHA_BAR_MIN = 1e-4
_COSINE_S = 0.008  # Nichol & Dhariwal (2021) offset.

ModelFn = Callable[[jnp.ndarray, jnp.ndarray], jnp.ndarray]


def alpha_bar(t: jnp.ndarray) -> jnp.ndarray:
  """Cosine schedule (Nichol & Dhariwal 2021): signal power alpha_bar(t), t in [0, 1]."""
  f = lambda u: jnp.cos(0.5 * math.pi * (u + _COSINE_S) / (1.0 + _COSINE_S)) ** 2
  return jnp.clip(f(jnp.asarray(t, jnp.float32)) / f(0.0), ALPHA_BAR_MIN, 1.0)


def _bcast(v: jnp.ndarray, x: jnp.ndarray) -> jnp.ndarray:
  """Right-pad v's shape with singleton axes so that it broadcasts against x."""
  v = jnp.asarray(v)
  return v.reshape(v.shape + (1,) * (x.ndim - v.ndim))


def q_sample(x0: jnp.ndarray, t: jnp.ndarray, eps: jnp.ndarray) -> jnp.ndarray:
  """Forward noising x_t = sqrt(ab) x0 + sqrt(1 - ab) eps; t has x0's leading batch shape."""
  ab = _bcast(alpha_bar(t), x0)
  return jnp.sqrt(ab) * x0 + jnp.sqrt(1.0 - ab) * eps


def split_prediction(pred: jnp.ndarray, x_t: jnp.ndarray, t: jnp.ndarray, prediction: str,
                     clip_x0: float | None = None):
  """Converts a model output into (x0_hat, eps_hat) for noisy input x_t at time t."""
  ab = _bcast(alpha_bar(t), x_t)
  if prediction == 'x0':
    x0 = pred
  elif prediction == 'eps':
    x0 = (x_t - jnp.sqrt(1.0 - ab) * pred) / jnp.sqrt(ab)
  else:
    raise ValueError(f"prediction must be 'x0' or 'eps', got {prediction!r}")
  if clip_x0 is not None:
    x0 = jnp.clip(x0, -clip_x0, clip_x0)
  eps = (x_t - jnp.sqrt(ab) * x0) / jnp.sqrt(1.0 - ab)
  return x0, eps


def denoising_loss(model_fn: ModelFn, x0: jnp.ndarray, key: jax.Array,
                   prediction: str = 'x0') -> jnp.ndarray:
  """Per-example simple diffusion loss: E_t,eps ||target - model(x_t, t)||^2 (mean over features).

  Args:
    model_fn: (x_t [B, ...], t [B]) -> prediction [B, ...].
    x0: [B, ...] clean samples.
    key: PRNG key for t ~ U(0, 1) and eps ~ N(0, I).
    prediction: what the model predicts, 'x0' or 'eps'.
  Returns:
    [B] losses.
  """
  t_key, eps_key = jax.random.split(key)
  t = jax.random.uniform(t_key, x0.shape[:1])
  eps = jax.random.normal(eps_key, x0.shape, x0.dtype)
  pred = model_fn(q_sample(x0, t, eps), t)
  target = x0 if prediction == 'x0' else eps
  err = (pred - target) ** 2
  return err.reshape(err.shape[0], -1).mean(axis=-1)


def sample(model_fn: ModelFn, x_init: jnp.ndarray, key: jax.Array, num_steps: int,
           eta: float = 1.0, prediction: str = 'x0', clip_x0: float | None = None,
           t_start: float = 1.0) -> jnp.ndarray:
  """Generalised DDIM sampler as one `lax.scan` over `num_steps` uniform steps.

  eta = 1 is DDPM ancestral sampling (posterior variance beta-tilde); eta = 0 is deterministic DDIM.
  x_init is the sample at t_start: standard normal noise for t_start = 1, or a noised earlier
  solution for warm starts (t_start < 1).

  Args:
    model_fn: (x_t [...], t []) -> prediction [...]; t is a scalar shared by the whole batch.
    x_init: [...] starting sample at time t_start.
    key: PRNG key; step i draws its noise from fold_in(key, i) (none when eta is a Python 0).
    num_steps: number of denoising steps (static).
    eta: stochasticity in [0, 1].
    prediction: 'x0' or 'eps'.
    clip_x0: clip predicted clean samples to [-clip_x0, clip_x0] (e.g. 1 for actions).
    t_start: time of x_init in (0, 1].
  Returns:
    [...] the denoised sample at t = 0.
  """
  if num_steps < 1:
    raise ValueError(f'num_steps must be >= 1, got {num_steps}')

  deterministic = isinstance(eta, (int, float)) and eta == 0  # DDIM: no noise to draw.

  def step(x, i):
    t = t_start * (num_steps - i) / num_steps
    s = t_start * (num_steps - i - 1) / num_steps
    x0, eps = split_prediction(model_fn(x, t), x, t, prediction, clip_x0)
    ab_t, ab_s = alpha_bar(t), alpha_bar(s)  # alpha_bar(0) = 1: the last step returns x0
    var = eta ** 2 * (1.0 - ab_s) / (1.0 - ab_t) * (1.0 - ab_t / ab_s)
    x_next = jnp.sqrt(ab_s) * x0 + jnp.sqrt(jnp.maximum(1.0 - ab_s - var, 0.0)) * eps
    if not deterministic:
      noise = jax.random.normal(jax.random.fold_in(key, i), x.shape, x.dtype)
      x_next = x_next + jnp.sqrt(var) * noise
    return x_next, None

  x, _ = jax.lax.scan(step, x_init, jnp.arange(num_steps))
  return x
