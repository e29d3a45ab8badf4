"""The loss terms (ld_mpc_jax.losses, and the kinds' own) against hand-computed values."""

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax import losses


def test_maxq_actor_climbs_a_toy_q(smoke_config):
  """The max-Q policy's gradient: with Q(z, a) = w . a (linear heads, z ignored), descending the
  actor loss moves the policy's mode toward sign(w) on every action dimension."""
  import optax
  from ld_mpc_jax import models
  from ld_mpc_jax.actors import maxq_actor_loss
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
