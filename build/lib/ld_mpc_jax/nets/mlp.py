"""Plain MLP blocks."""

from typing import Callable, Sequence

import flax.linen as nn
import jax.numpy as jnp


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
