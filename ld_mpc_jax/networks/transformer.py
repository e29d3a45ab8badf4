"""Transformer blocks and Fourier embeddings shared by the diffusion and objective models."""

import math
from typing import Optional

import flax.linen as nn
import jax.numpy as jnp


def fourier_features(x: jnp.ndarray, dim: int, max_period: float = 10_000.0) -> jnp.ndarray:
  """Sinusoidal features of a scalar (diffusion time or sequence position).

  Args:
    x: [...] real values (t in [0, 1] is scaled by 1000 by the caller if wanted).
    dim: even number of output features.
    max_period: longest wavelength.
  Returns:
    [..., dim] = [cos(x * f_k), sin(x * f_k)] with log-spaced frequencies f_k.
  """
  if dim % 2:
    raise ValueError(f'fourier_features needs an even dim, got {dim}')
  half = dim // 2
  freqs = jnp.exp(-math.log(max_period) * jnp.arange(half, dtype=jnp.float32) / half)
  args = jnp.asarray(x, jnp.float32)[..., None] * freqs
  return jnp.concatenate([jnp.cos(args), jnp.sin(args)], axis=-1)


class TimeEmbedding(nn.Module):
  """Diffusion time t in [0, 1] -> [..., width] via Fourier features and a small MLP."""
  width: int

  @nn.compact
  def __call__(self, t: jnp.ndarray) -> jnp.ndarray:
    h = fourier_features(1000.0 * t, self.width)
    h = nn.Dense(self.width, name='dense_0')(h)
    h = nn.Dense(self.width, name='dense_1')(nn.silu(h))
    return h


def position_embedding(num: int, width: int) -> jnp.ndarray:
  """Fixed Fourier embedding of positions 0..num-1 -> [num, width]."""
  return fourier_features(jnp.arange(num, dtype=jnp.float32), width, max_period=100.0)


class TransformerBlock(nn.Module):
  """Pre-LayerNorm transformer block: x + MHA(LN(x)); x + MLP(LN(x)).

  Attributes:
    num_heads: attention heads (width must be divisible by it).
    mlp_ratio: hidden width of the MLP relative to the model width.
    dropout: dropout rate on attention weights and residual branches.
  """
  num_heads: int
  mlp_ratio: int = 4
  dropout: float = 0.0

  @nn.compact
  def __call__(self, x: jnp.ndarray, mask: Optional[jnp.ndarray] = None,
               deterministic: bool = True) -> jnp.ndarray:
    """x: [..., L, W]; mask: broadcastable to [..., heads, L, L] (True = attend)."""
    width = x.shape[-1]
    h = nn.LayerNorm(name='ln_attn')(x)
    h = nn.MultiHeadDotProductAttention(
        num_heads=self.num_heads, dropout_rate=self.dropout,
        deterministic=deterministic, name='attn')(h, h, mask=mask)
    x = x + nn.Dropout(self.dropout)(h, deterministic=deterministic)
    h = nn.LayerNorm(name='ln_mlp')(x)
    h = nn.Dense(self.mlp_ratio * width, name='mlp_in')(h)
    h = nn.Dense(width, name='mlp_out')(nn.gelu(h))
    return x + nn.Dropout(self.dropout)(h, deterministic=deterministic)


class Transformer(nn.Module):
  """A stack of `num_blocks` TransformerBlocks followed by a final LayerNorm."""
  num_blocks: int
  num_heads: int
  mlp_ratio: int = 4
  dropout: float = 0.0

  @nn.compact
  def __call__(self, x: jnp.ndarray, mask: Optional[jnp.ndarray] = None,
               deterministic: bool = True) -> jnp.ndarray:
    """x: [..., L, W] -> [..., L, W]."""
    for i in range(self.num_blocks):
      x = TransformerBlock(self.num_heads, self.mlp_ratio, self.dropout,
                           name=f'block_{i}')(x, mask, deterministic)
    return nn.LayerNorm(name='ln_final')(x)
