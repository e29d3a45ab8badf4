"""ld_mpc_jax.model.dynamics: the deterministic MLP kind's transition (the diffusion kinds' losses are in
tests/test_losses.py, their rollouts in tests/test_planner.py and tests/e2e)."""

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.cli import ablations
from ld_mpc_jax.model import dynamics, models
from ld_mpc_jax.model.settings import ModelSettings


def test_mlp_dynamics_stays_on_the_encoder_sphere(smoke_config):
  config = ablations.with_overrides(smoke_config, {'model.dynamics_type': 'mlp'})
  params = models.init_params(config, jax.random.key(0))
  nets = models.build_networks(ModelSettings.from_config(config))
  d = config.model.latent_dim
  z_next = nets.dynamics.apply({'params': params['dynamics']}, jnp.ones((3, d)),
                               jnp.zeros((3, config.action_dim)))
  np.testing.assert_allclose(jnp.sqrt(jnp.mean(z_next ** 2, -1)), 1.0, rtol=1e-4)




def test_mlp_transition_is_the_module_and_ignores_the_key(smoke_config):
  config = ablations.with_overrides(smoke_config, {'model.dynamics_type': 'mlp'})
  params = models.init_params(config, jax.random.key(0))
  module = models.build_networks(ModelSettings.from_config(config)).dynamics
  step = dynamics.make_transition(ModelSettings.from_config(config), module,
      config.plan.dynamics_steps, config.plan.dynamics_eta)
  z = jax.random.normal(jax.random.key(1), (3, config.model.latent_dim))
  a = jnp.linspace(-1, 1, 3 * config.action_dim).reshape(3, -1)
  want = module.apply({'params': params['dynamics']}, z, a)
  np.testing.assert_allclose(step(params, z, a, jax.random.key(2)), want, rtol=1e-6)
  np.testing.assert_allclose(step(params, z, a, jax.random.key(3)), want, rtol=1e-6)
