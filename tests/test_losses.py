"""Symlog / two-hot helpers and return targets against hand-computed values."""

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax import losses


def test_symlog_symexp_values_and_round_trip():
  np.testing.assert_allclose(losses.symlog(jnp.array([0.0, np.e - 1, -(np.e - 1)])),
                             [0.0, 1.0, -1.0], atol=1e-6)
  x = jnp.array([-500.0, -3.0, -0.1, 0.0, 0.2, 7.0, 1000.0])
  np.testing.assert_allclose(losses.symexp(losses.symlog(x)), x, rtol=1e-5)


def test_two_hot_hand_values():
  # 5 bins on [-2, 2]: centres -2, -1, 0, 1, 2 (symlog space).
  enc = lambda x: losses.two_hot(jnp.asarray(x, jnp.float32), 5, -2.0, 2.0)
  np.testing.assert_allclose(enc(0.0), [0, 0, 1, 0, 0], atol=1e-6)
  np.testing.assert_allclose(enc(np.expm1(0.25)), [0, 0, 0.75, 0.25, 0], atol=1e-6)
  np.testing.assert_allclose(enc(-np.expm1(1.5)), [0.5, 0.5, 0, 0, 0], atol=1e-6)
  np.testing.assert_allclose(enc(100.0), [0, 0, 0, 0, 1], atol=1e-6)  # Clipped at vmax.
  np.testing.assert_allclose(enc(-np.expm1(2.0)), [1, 0, 0, 0, 0], atol=1e-6)


def test_two_hot_decode_round_trip():
  x = jnp.array([-300.0, -2.5, 0.0, 0.3, 9.0, 400.0])
  probs = losses.two_hot(x, 101, -10.0, 10.0)
  np.testing.assert_allclose(probs.sum(-1), 1.0, rtol=1e-6)
  decoded = losses.two_hot_decode(jnp.log(probs), -10.0, 10.0)
  np.testing.assert_allclose(decoded, x, rtol=1e-4, atol=1e-5)


def test_soft_cross_entropy_hand_value():
  logits = jnp.log(jnp.array([0.5, 0.25, 0.25]))
  target = jnp.array([0.0, 1.0, 0.0])
  np.testing.assert_allclose(losses.soft_cross_entropy(logits, target), np.log(4.0), rtol=1e-6)


def test_discounted_return_and_n_step_targets():
  r, v, g = jnp.array([1.0, 2.0, 3.0]), jnp.array(10.0), 0.5
  # 1 + 0.5 * 2 + 0.25 * 3 + 0.125 * 10 = 4.0
  np.testing.assert_allclose(losses.discounted_return(r, v, g), 4.0, rtol=1e-6)
  # V2 = 3 + 5 = 8, V1 = 2 + 4 = 6, V0 = 1 + 3 = 4.
  np.testing.assert_allclose(losses.n_step_targets(r, v, g), [4.0, 6.0, 8.0], rtol=1e-6)
  batch = losses.n_step_targets(jnp.stack([r, 2 * r]), jnp.array([10.0, 0.0]), g)
  np.testing.assert_allclose(batch, [[4.0, 6.0, 8.0], [5.5, 7.0, 6.0]], rtol=1e-6)


def test_maxq_actor_climbs_a_toy_q(smoke_config):
  """The max-Q policy's gradient: with Q(z, a) = w . a (linear heads, z ignored), descending the
  actor loss moves the policy's mode toward sign(w) on every action dimension."""
  import optax
  from ld_mpc_jax import models
  from ld_mpc_jax.losses import maxq_actor_loss
  c = smoke_config
  c.objective.actor, c.objective.hidden = 'maxq', ()
  nets = models.build_networks(c)
  params = models.init_params(c, jax.random.key(0))
  d = c.model.latent_dim
  w = np.array([1.0, -1.0, 1.0, -1.0], np.float32)
  kernel = np.zeros(params['critics']['q']['heads']['dense_0']['kernel'].shape, np.float32)
  kernel[:, d:, 0] = w  # Q_j(z, a) = w . a for both heads.
  params['critics']['q']['heads']['dense_0']['kernel'] = jnp.asarray(kernel)
  params['critics']['q']['heads']['dense_0']['bias'] *= 0.0
  z = jax.random.normal(jax.random.key(1), (16, d))
  mode = lambda p: nets.actor.apply({'params': p['actor']}, z)
  before = float(jnp.mean(mode(params) @ w))
  opt = optax.adam(1e-2)
  state = opt.init(params)
  grad_fn = jax.jit(jax.grad(lambda p, k: maxq_actor_loss(nets, p, z, k, 1e-4)))
  for i in range(100):
    g = grad_fn(params, jax.random.key(i))
    assert float(jnp.abs(g['critics']['q']['heads']['dense_0']['kernel']).max()) == 0.0
    updates, state = opt.update(g, state, params)
    params = optax.apply_updates(params, updates)
  after = mode(params)
  assert float(jnp.mean(after @ w)) > before + 1.0
  assert bool(jnp.all(jnp.sign(jnp.mean(after, 0)) == w))
