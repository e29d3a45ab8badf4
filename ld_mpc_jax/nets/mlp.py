"""Plain MLP blocks."""

from typing import Callable, Sequence

import flax.linen as nn
import jax.numpy as jnp

from ld_mpc_jax.ops.numerics import rms_normalize, simnorm


def mish(x: jnp.ndarray) -> jnp.ndarray:
  """x tanh(softplus(x)), the function of jax.nn.mish, with one exp instead of exp, log1p and
  tanh: tanh(log(1 + e)) = n / (n + 2) with n = e (e + 2), e = exp(x). XLA:CPU evaluates it
  faster, forward and backward. Above x = 20 the factor is 1 in float32, so exp is clipped there.
  """
  e = jnp.exp(jnp.minimum(x, 20.0))
  n = e * (e + 2.0)
  return x * n / (n + 2.0)


class MLP(nn.Module):
  """Dense layers with LayerNorm + Mish between them (as in TD-MPC2's mlp).

  Attributes:
    features: output width of every layer; the last entry is the output size.
    activate_final: apply LayerNorm + activation after the last layer too.
    activation: non-linearity between layers.
  """
  features: Sequence[int]
  activate_final: bool = False
  activation: Callable[[jnp.ndarray], jnp.ndarray] = mish

  @nn.compact
  def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
    """x: [..., d_in] -> [..., features[-1]]."""
    for i, width in enumerate(self.features):
      x = nn.Dense(width, name=f'dense_{i}')(x)
      if i < len(self.features) - 1 or self.activate_final:
        x = nn.LayerNorm(name=f'norm_{i}')(x)
        x = self.activation(x)
    return x


# How a latent is put on its manifold (`config.model.latent_norm`): 'rms' scales it to unit
# root-mean-square (no parameters); 'simnorm' is TD-MPC2's last layer, LayerNorm then SimNorm
# (softmax over groups of 8), whose LayerNorm parameters are named 'latent_norm'.
LATENT_NORMS = ('rms', 'simnorm')


def normalize_latent(x: jnp.ndarray, kind: str) -> jnp.ndarray:
  """x [..., D] on the latent manifold of `kind` (LATENT_NORMS); call it inside a compact
  method: 'simnorm' adds the enclosing module's LayerNorm 'latent_norm'."""
  if kind == 'simnorm':
    return simnorm(nn.LayerNorm(name='latent_norm')(x))
  if kind != 'rms':
    raise ValueError(f'config.model.latent_norm must be one of {LATENT_NORMS}, got {kind!r}')
  return rms_normalize(x)
