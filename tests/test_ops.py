"""ld_mpc_jax.ops.numerics: symlog / two-hot helpers and return targets against hand-computed values."""

import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.ops import numerics as ops


def test_symlog_symexp_values_and_round_trip():
  np.testing.assert_allclose(ops.symlog(jnp.array([0.0, np.e - 1, -(np.e - 1)])),
                             [0.0, 1.0, -1.0], atol=1e-6)
  x = jnp.array([-500.0, -3.0, -0.1, 0.0, 0.2, 7.0, 1000.0])
  np.testing.assert_allclose(ops.symexp(ops.symlog(x)), x, rtol=1e-5)


def test_two_hot_hand_values():
  # 5 bins on [-2, 2]: centres -2, -1, 0, 1, 2 (symlog space).
  enc = lambda x: ops.two_hot(jnp.asarray(x, jnp.float32), 5, -2.0, 2.0)
  np.testing.assert_allclose(enc(0.0), [0, 0, 1, 0, 0], atol=1e-6)
  np.testing.assert_allclose(enc(np.expm1(0.25)), [0, 0, 0.75, 0.25, 0], atol=1e-6)
  np.testing.assert_allclose(enc(-np.expm1(1.5)), [0.5, 0.5, 0, 0, 0], atol=1e-6)
  np.testing.assert_allclose(enc(100.0), [0, 0, 0, 0, 1], atol=1e-6)  # Clipped at vmax.
  np.testing.assert_allclose(enc(-np.expm1(2.0)), [1, 0, 0, 0, 0], atol=1e-6)


def test_two_hot_decode_round_trip():
  x = jnp.array([-300.0, -2.5, 0.0, 0.3, 9.0, 400.0])
  probs = ops.two_hot(x, 101, -10.0, 10.0)
  np.testing.assert_allclose(probs.sum(-1), 1.0, rtol=1e-6)
  decoded = ops.two_hot_decode(jnp.log(probs), -10.0, 10.0)
  np.testing.assert_allclose(decoded, x, rtol=1e-4, atol=1e-5)


def test_soft_cross_entropy_hand_value():
  logits = jnp.log(jnp.array([0.5, 0.25, 0.25]))
  target = jnp.array([0.0, 1.0, 0.0])
  np.testing.assert_allclose(ops.soft_cross_entropy(logits, target), np.log(4.0), rtol=1e-6)


def test_discounted_return_and_n_step_targets():
  r, v, g = jnp.array([1.0, 2.0, 3.0]), jnp.array(10.0), 0.5
  # 1 + 0.5 * 2 + 0.25 * 3 + 0.125 * 10 = 4.0
  np.testing.assert_allclose(ops.discounted_return(r, v, g), 4.0, rtol=1e-6)
  # V2 = 3 + 5 = 8, V1 = 2 + 4 = 6, V0 = 1 + 3 = 4.
  np.testing.assert_allclose(ops.window_returns(r, v, g), [4.0, 6.0, 8.0], rtol=1e-6)
  batch = ops.window_returns(jnp.stack([r, 2 * r]), jnp.array([10.0, 0.0]), g)
  np.testing.assert_allclose(batch, [[4.0, 6.0, 8.0], [5.5, 7.0, 6.0]], rtol=1e-6)
