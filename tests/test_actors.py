"""ld_mpc_jax.model.actors: the actor's mode and its tanh-Gaussian sample with log-probability, and the
weighted regression loss, against hand-computed values. (Each kind's loss term is in
tests/test_losses.py.)"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats as sps

from ld_mpc_jax.model import actors

MEAN, LOG_STD = np.array([0.3, -0.8]), np.array([-0.5, -12.0])  # The second is clipped to -10.


def _actor(log_std_map='clip'):
  """A stochastic actor with no hidden layer whose output ignores z: mean and log-std fixed."""
  actor = actors.Actor(hidden=(), action_dim=2, stochastic=True, log_std_map=log_std_map)
  params = actor.init(jax.random.key(0), jnp.zeros((1, 3)))
  dense = params['params']['mlp']['dense_0']
  assert dense['kernel'].shape == (3, 4)
  params = {'params': {'mlp': {'dense_0': dict(kernel=jnp.zeros((3, 4)),
                                               bias=jnp.asarray(np.r_[MEAN, LOG_STD]))}}}
  return actor, params


def test_mode_is_the_tanh_of_the_mean():
  actor, params = _actor()
  np.testing.assert_allclose(actor.apply(params, jnp.ones((5, 3))),
                             np.broadcast_to(np.tanh(MEAN), (5, 2)), rtol=1e-6)


def test_sample_and_log_probability_by_the_change_of_variables():
  actor, params = _actor()
  z, key = jnp.ones((4, 3)), jax.random.key(7)
  a, log_prob = actor.apply(params, z, key, method=actors.Actor.sample)
  std = np.exp(np.clip(LOG_STD, -10.0, 2.0))
  u = MEAN + std * np.asarray(jax.random.normal(key, (4, 2)))  # The same draw.
  np.testing.assert_allclose(a, np.tanh(u), rtol=1e-5, atol=1e-6)
  # log N(u; mean, std) less log |d tanh(u) / du| per dimension.
  want = np.sum(sps.norm.logpdf(u, MEAN, std) - np.log(1.0 - np.tanh(u) ** 2 + 1e-6), axis=-1)
  np.testing.assert_allclose(log_prob, want, rtol=1e-4)
  assert np.all(np.abs(a) < 1.0)


def test_tdmpc2_log_std_map_hand_computed():
  # -10 + 6 (tanh(x) + 1): -4 at 0, within [-10, 2], and not clipped (a gradient everywhere).
  x = jnp.array([0.0, 1.0, -30.0, 30.0])
  want = -10.0 + 6.0 * (np.tanh(np.asarray(x)) + 1.0)
  np.testing.assert_allclose(actors.log_std_from(x, 'tanh'), want, rtol=1e-6)
  assert float(actors.log_std_from(jnp.zeros(()), 'tanh')) == pytest.approx(-4.0)
  np.testing.assert_allclose(actors.log_std_from(x, 'clip'), [0.0, 1.0, -10.0, 2.0])
  grad = jax.grad(lambda v: actors.log_std_from(v, 'tanh'))(3.0)
  assert float(grad) == pytest.approx(6.0 * (1.0 - np.tanh(3.0) ** 2), rel=1e-5)
  with pytest.raises(ValueError, match='log_std_map'):
    actors.log_std_from(x, 'softplus')


def test_tanh_map_sample_uses_the_mapped_std():
  actor, params = _actor('tanh')
  z, key = jnp.ones((4, 3)), jax.random.key(7)
  a, log_prob = actor.apply(params, z, key, method=actors.Actor.sample)
  std = np.exp(-10.0 + 6.0 * (np.tanh(LOG_STD) + 1.0))
  u = MEAN + std * np.asarray(jax.random.normal(key, (4, 2)))
  np.testing.assert_allclose(a, np.tanh(u), rtol=1e-5, atol=1e-6)
  want = np.sum(sps.norm.logpdf(u, MEAN, std) - np.log(1.0 - np.tanh(u) ** 2 + 1e-6), axis=-1)
  np.testing.assert_allclose(log_prob, want, rtol=1e-4)


def test_weighted_bc_loss_hand_computed():
  a_pi = jnp.array([[0.0, 0.0], [1.0, 1.0]])
  action = jnp.array([[1.0, 2.0], [1.0, 0.0]])  # Squared distances 5 and 1.
  assert float(actors.weighted_bc_loss(a_pi, action, jnp.array([2.0, 3.0]))) == pytest.approx(
      (2 * 5 + 3 * 1) / 2)
  assert float(actors.weighted_bc_loss(a_pi, action, jnp.zeros(2))) == 0.0
