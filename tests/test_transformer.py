"""ld_mpc_jax.nets.transformer: attention equals flax's, `outputs` equals the sliced full
output, gelu is flax's."""

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.nets import SelfAttention, Transformer
from ld_mpc_jax.nets.transformer import SHORT_SEQUENCE, gelu


@pytest.mark.parametrize('length', [1, 3, SHORT_SEQUENCE, SHORT_SEQUENCE + 1])
@pytest.mark.parametrize('causal', [False, True])
def test_self_attention_matches_flax_attention(length, causal):
  """Same parameter tree as nn.MultiHeadDotProductAttention, and the same outputs with its
  parameters (short and long code paths, with and without a mask)."""
  x = jax.random.normal(jax.random.key(0), (2, 3, length, 16))
  mask = nn.make_causal_mask(jnp.ones(x.shape[:-1])) if causal else None
  theirs = nn.MultiHeadDotProductAttention(num_heads=4)
  params = jax.jit(theirs.init)(jax.random.key(1), x, x)  # Jitted: op by op compiles many.
  ours = SelfAttention(num_heads=4)
  shapes = lambda p: jax.tree_util.tree_map(lambda leaf: tuple(leaf.shape), p)
  ours_tree = jax.eval_shape(ours.init, jax.random.key(1), x)  # Traced, not compiled.
  assert jax.tree_util.tree_structure(ours_tree) == jax.tree_util.tree_structure(params)
  assert shapes(ours_tree) == shapes(params)
  expected = jax.jit(lambda p: theirs.apply(p, x, x, mask=mask))(params)
  np.testing.assert_allclose(jax.jit(lambda p: ours.apply(p, x, mask))(params), expected,
                             atol=1e-5)
  # A single query (the short path's unrolled scores) against the same row of the full output.
  last = slice(length - 1, None)
  np.testing.assert_allclose(jax.jit(lambda p: ours.apply(p, x, mask, queries=last))(params),
                             expected[..., last, :], atol=1e-5)
  # Training passes (deterministic=False, here without dropout) take the matmul path.
  training = jax.jit(lambda p: ours.apply(p, x, mask, deterministic=False))
  np.testing.assert_allclose(training(params), expected, atol=1e-5)


def test_self_attention_rejects_indivisible_width():
  with pytest.raises(ValueError, match='divisible'):
    SelfAttention(num_heads=3).init(jax.random.key(0), jnp.ones((2, 4, 16)))


@pytest.mark.parametrize('length,outputs', [(3, slice(2, None)), (5, slice(1, None)),
                                            (SHORT_SEQUENCE + 1, slice(1, None))])
def test_transformer_outputs_equal_sliced_full_output(length, outputs):
  tr = Transformer(num_blocks=2, num_heads=2)
  x = jax.random.normal(jax.random.key(0), (4, length, 8))
  params = jax.jit(tr.init)(jax.random.key(1), x)  # Jitted: op by op compiles many programs.
  full = jax.jit(tr.apply)(params, x)
  apply_part = jax.jit(lambda p, x: tr.apply(p, x, outputs=outputs))
  part = apply_part(params, x)
  assert part.shape == full[:, outputs].shape
  np.testing.assert_allclose(part, full[:, outputs], atol=1e-5)
  # The tokens left out still act as keys and values: changing one changes the output.
  moved = apply_part(params, x.at[:, 0].multiply(-1.0))
  assert np.abs(moved - part).max() > 1e-3


def test_gelu_is_flax_gelu():
  x = jnp.linspace(-6.0, 6.0, 1001)
  np.testing.assert_allclose(gelu(x), nn.gelu(x), atol=1e-6)
  assert float(gelu(jnp.array(1.0))) == pytest.approx(0.841192, abs=1e-5)
