"""Transformer blocks and Fourier embeddings shared by the diffusion and objective models."""

import math
from typing import Optional

import flax.linen as nn
import jax
import jax.numpy as jnp

# Deterministic passes (deterministic=True: planning, EMA targets, and the training rollout
# through the dynamics model) of sequences up to this length compute attention scores and
# mixing as broadcast products (element-wise fusions); longer ones, and passes with dropout on
# (the training losses' own passes), as batched matmuls. On XLA:CPU the element-wise form is
# faster at the planner's lengths (3 tokens in the dynamics, 5 in the proposal;
# docs/benchmark.md); the training update was not slower with its loss passes as matmuls
# (docs/scaling.md).
SHORT_SEQUENCE = 8


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


class _Projection(nn.Module):
  """The kernel [W, heads, head_dim] and bias [heads, head_dim] of one of q, k, v.

  Declared like flax's DenseGeneral (same names, shapes and initialisers) but not applied, so
  that SelfAttention can do the three projections as one matmul.
  """
  width: int
  num_heads: int
  head_dim: int

  @nn.compact
  def __call__(self):
    shape = (self.width, self.num_heads, self.head_dim)
    init = lambda key, shape: nn.initializers.lecun_normal()(
        key, (shape[0], shape[1] * shape[2])).reshape(shape)
    return (self.param('kernel', init, shape),
            self.param('bias', nn.initializers.zeros_init(), shape[1:]))


class SelfAttention(nn.Module):
  """Multi-head self-attention, the function and parameters of nn.MultiHeadDotProductAttention.

  Parameters are flax's ('query', 'key', 'value': kernels [W, heads, head_dim] and biases;
  'out': DenseGeneral back to the width), so checkpoints written with flax's module load
  unchanged and give the same outputs. What differs is the computation, for speed at the short
  sequences of the planner: Q, K and V come from one [W, 3W] matmul (for every token, also when
  only some queries are wanted), the scores and the mixing are broadcast products for short
  sequences in deterministic passes (see SHORT_SEQUENCE), and dropout on the attention weights
  is drawn per element rather than broadcast over the batch.

  Attributes:
    num_heads: attention heads (width must be divisible by it).
    dropout: dropout rate on the attention weights.
  """
  num_heads: int
  dropout: float = 0.0

  @nn.compact
  def __call__(self, x: jnp.ndarray, mask: Optional[jnp.ndarray] = None,
               deterministic: bool = True, queries: Optional[slice] = None) -> jnp.ndarray:
    """Attention of the tokens `queries` (all if None) to every token of x.

    Args:
      x: [..., L, W] tokens.
      mask: broadcastable to [..., heads, L, L] (True = attend), or None.
      deterministic: no dropout.
      queries: a slice of the L positions whose outputs are wanted (Q of L_q tokens).
    Returns:
      [..., L_q, W].
    """
    width, length = x.shape[-1], x.shape[-2]
    if width % self.num_heads:
      raise ValueError(f'width {width} is not divisible by num_heads {self.num_heads}')
    head_dim = width // self.num_heads
    kernels, biases = zip(*(_Projection(width, self.num_heads, head_dim, name=name)()
                            for name in ('query', 'key', 'value')))
    qkv = x @ jnp.stack(kernels, axis=1).reshape(width, 3 * width) + jnp.stack(biases).reshape(-1)
    qkv = qkv.reshape(x.shape[:-1] + (3, self.num_heads, head_dim))
    q, k, v = qkv[..., 0, :, :], qkv[..., 1, :, :], qkv[..., 2, :, :]  # [..., L, heads, hd]
    if queries is not None:
      q = q[..., queries, :, :]
      if mask is not None:
        mask = mask[..., queries, :]
    q = q / math.sqrt(head_dim)
    if length <= SHORT_SEQUENCE and deterministic:
      # scores [..., Lq, Lk, heads], softmax over Lk; mixing unrolled over the Lk keys.
      scores = _sum_last_axis(q[..., :, None, :, :] * k[..., None, :, :, :])
      if mask is not None:
        mask = jnp.moveaxis(mask, -3, -1)  # [..., heads, Lq, Lk] -> [..., Lq, Lk, heads]
      weights = self._weights(scores, mask, axis=-2, deterministic=deterministic)
      out = sum(weights[..., j, :, None] * v[..., None, j, :, :] for j in range(length))
    else:
      q, k, v = (jnp.swapaxes(y, -2, -3) for y in (q, k, v))  # [..., heads, L, head_dim]
      weights = self._weights(q @ jnp.swapaxes(k, -1, -2), mask, axis=-1,
                              deterministic=deterministic)
      out = jnp.swapaxes(weights @ v, -2, -3)
    return nn.DenseGeneral(width, axis=(-2, -1), name='out')(out)

  def _weights(self, scores, mask, axis: int, deterministic: bool):
    if mask is not None:
      scores = jnp.where(mask, scores, jnp.finfo(scores.dtype).min)
    weights = jax.nn.softmax(scores, axis=axis)
    return nn.Dropout(self.dropout)(weights, deterministic=deterministic)


def _sum_last_axis(x: jnp.ndarray) -> jnp.ndarray:
  """jnp.sum(x, axis=-1) as a tree of halvings: XLA:CPU fuses it into one element-wise loop,
  faster than its reduction at the planner's sizes (the attention scores over head_dim)."""
  while x.shape[-1] > 1 and x.shape[-1] % 2 == 0:
    half = x.shape[-1] // 2
    x = x[..., :half] + x[..., half:]
  return jnp.sum(x, axis=-1)


def gelu(x: jnp.ndarray) -> jnp.ndarray:
  """tanh-approximate GELU, the function of nn.gelu, in a form XLA:CPU evaluates faster."""
  return 0.5 * x * (1.0 + jnp.tanh(math.sqrt(2.0 / math.pi) * x * (1.0 + 0.044715 * x * x)))


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
               deterministic: bool = True, outputs: Optional[slice] = None) -> jnp.ndarray:
    """x: [..., L, W]; mask: broadcastable to [..., heads, L, L] (True = attend).

    Returns [..., L, W], or only the tokens `outputs` (a slice of the L positions): their
    queries attend to every token, and the MLP runs on them alone.
    """
    width = x.shape[-1]
    h = nn.LayerNorm(name='ln_attn')(x)
    h = SelfAttention(self.num_heads, self.dropout, name='attn')(h, mask, deterministic, outputs)
    if outputs is not None:
      x = x[..., outputs, :]
    x = x + nn.Dropout(self.dropout)(h, deterministic=deterministic)
    h = nn.LayerNorm(name='ln_mlp')(x)
    h = nn.Dense(self.mlp_ratio * width, name='mlp_in')(h)
    h = nn.Dense(width, name='mlp_out')(gelu(h))
    return x + nn.Dropout(self.dropout)(h, deterministic=deterministic)


class Transformer(nn.Module):
  """A stack of `num_blocks` TransformerBlocks followed by a final LayerNorm."""
  num_blocks: int
  num_heads: int
  mlp_ratio: int = 4
  dropout: float = 0.0

  @nn.compact
  def __call__(self, x: jnp.ndarray, mask: Optional[jnp.ndarray] = None,
               deterministic: bool = True, outputs: Optional[slice] = None) -> jnp.ndarray:
    """x: [..., L, W] -> [..., L, W], or [..., L_out, W] for the tokens `outputs`.

    `outputs` (a slice of the L positions) is what the caller reads: the last block computes
    only those tokens (every token still serves as key and value), which saves its
    projections and MLP on the others. The result equals the full output sliced.
    """
    for i in range(self.num_blocks):
      last = i == self.num_blocks - 1
      x = TransformerBlock(self.num_heads, self.mlp_ratio, self.dropout,
                           name=f'block_{i}')(x, mask, deterministic, outputs if last else None)
    return nn.LayerNorm(name='ln_final')(x)
