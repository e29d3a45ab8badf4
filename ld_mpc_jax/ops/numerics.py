"""Pure array math shared by the losses, the planner and MPPI: symlog, two-hot regression,
discounted returns, RMS and simplicial normalisation. No flax, no config."""

import jax
import jax.numpy as jnp
import optax


def symlog(x: jnp.ndarray) -> jnp.ndarray:
  """sign(x) log(1 + |x|)."""
  return jnp.sign(x) * jnp.log1p(jnp.abs(x))


def symexp(x: jnp.ndarray) -> jnp.ndarray:
  """Inverse of symlog: sign(x) (exp|x| - 1)."""
  return jnp.sign(x) * jnp.expm1(jnp.abs(x))


def bin_centers(num_bins: int, vmin: float, vmax: float) -> jnp.ndarray:
  """[num_bins] evenly spaced bin centres in symlog space."""
  return jnp.linspace(vmin, vmax, num_bins)


def two_hot(x: jnp.ndarray, num_bins: int, vmin: float, vmax: float) -> jnp.ndarray:
  """Two-hot encoding of symlog(x) over bins on [vmin, vmax]: [...] -> [..., num_bins].

  The mass is split between the two nearest bins in proportion to proximity, so the expected
  bin value equals clip(symlog(x), vmin, vmax) exactly.
  """
  y = jnp.clip(symlog(x), vmin, vmax)
  pos = (y - vmin) / (vmax - vmin) * (num_bins - 1)
  lo = jnp.clip(jnp.floor(pos), 0, num_bins - 2)
  frac = pos - lo
  lo = lo.astype(jnp.int32)
  return (jax.nn.one_hot(lo, num_bins) * (1.0 - frac)[..., None]
          + jax.nn.one_hot(lo + 1, num_bins) * frac[..., None])


def two_hot_decode(logits: jnp.ndarray, vmin: float, vmax: float) -> jnp.ndarray:
  """Scalar prediction of two-hot logits [..., num_bins] -> [...]: symexp(E_softmax[bin])."""
  centers = bin_centers(logits.shape[-1], vmin, vmax)
  return symexp(jnp.sum(jax.nn.softmax(logits, axis=-1) * centers, axis=-1))


def soft_cross_entropy(logits: jnp.ndarray, target_probs: jnp.ndarray) -> jnp.ndarray:
  """-sum_k p_k log softmax(logits)_k over the last axis (optax.softmax_cross_entropy)."""
  return optax.softmax_cross_entropy(logits, target_probs)


def discounted_return(rewards: jnp.ndarray, terminal_value: jnp.ndarray,
                      gamma: float) -> jnp.ndarray:
  """J = sum_{i<H} gamma^i r_i + gamma^H V: rewards [..., H], terminal_value [...] -> [...]."""
  horizon = rewards.shape[-1]
  discounts = gamma ** jnp.arange(horizon, dtype=rewards.dtype)
  return jnp.sum(rewards * discounts, axis=-1) + gamma ** horizon * terminal_value


def window_returns(rewards: jnp.ndarray, bootstrap: jnp.ndarray, gamma: float) -> jnp.ndarray:
  """Targets sum_{j>=i} gamma^(j-i) r_j + gamma^(T-i) bootstrap for every i < T.

  rewards [..., T], bootstrap [...] (value after the last reward) -> [..., T].
  """
  def step(carry, r):
    g = r + gamma * carry
    return g, g
  _, out = jax.lax.scan(step, bootstrap, jnp.moveaxis(rewards, -1, 0), reverse=True)
  return jnp.moveaxis(out, 0, -1)


def rms_normalize(x: jnp.ndarray, eps: float = 1e-6) -> jnp.ndarray:
  """Scales each vector [..., D] to unit root-mean-square: the latent then matches N(0, I)'s
  scale."""
  return x * jax.lax.rsqrt(jnp.mean(x ** 2, axis=-1, keepdims=True) + eps)


# TD-MPC2's SimNorm group size (its `simnorm_dim`).
SIMNORM_GROUP = 8


def simnorm(x: jnp.ndarray, group: int = SIMNORM_GROUP) -> jnp.ndarray:
  """Simplicial normalisation (TD-MPC2, Hansen et al. 2024): the last axis [..., D] split into
  D / group consecutive groups, each a softmax, so every group lies on a simplex."""
  g = x.reshape(x.shape[:-1] + (x.shape[-1] // group, group))
  return jax.nn.softmax(g, axis=-1).reshape(x.shape)
