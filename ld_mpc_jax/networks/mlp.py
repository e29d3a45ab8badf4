"""Plain MLP blocks."""

from typing import Callable, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp


class MLP(nn.Module):
  """Dense layers with LayerNorm + Mish between them (as in TD-MPC2's mlp).

  Attributes:
    features: output width of every layer; the last entry is the output size.
    activate_final: apply LayerNorm + activation after the last layer too.
    activation: non-linearity between layers.
  """
  features: Sequence[int]
  activate_final: bool = False
  activation: Callable[[jnp.ndarray], jnp.ndarray] = jax.nn.mish

  @nn.compact
  def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
    """x: [..., d_in] -> [..., features[-1]]."""
    for i, width in enumerate(self.features):
      x = nn.Dense(width, name=f'dense_{i}')(x)
      if i < len(self.features) - 1 or self.activate_final:
        x = nn.LayerNorm(name=f'norm_{i}')(x)
        x = self.activation(x)
    return x
