"""ld_mpc_jax.model.proposals: teacher-forced pairs of a window, the Gaussian single-step proposal's draw
and bounds, single-step proposals inside the planner's rollout. (Each kind's loss term is in
tests/test_losses.py.)"""

import types

import chex
import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from ld_mpc_jax.cli import ablations
from ld_mpc_jax.model import models, proposals
from ld_mpc_jax.plan import planner
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings


def test_transitions_pair_each_latent_with_its_action():
  z = jnp.arange(2 * 4 * 3, dtype=jnp.float32).reshape(2, 4, 3)  # [B=2, H+2=4, D=3]
  action = -jnp.arange(2 * 3 * 2, dtype=jnp.float32).reshape(2, 3, 2)  # [B, H+1=3, A=2]
  z_in, a_in = proposals.transitions(z, action)
  assert z_in.shape == (6, 3) and a_in.shape == (6, 2)
  for b in range(2):
    for i in range(3):  # Row b (H+1) + i is (z_i, a_i) of window b; z_{H+1} is never an input.
      np.testing.assert_array_equal(z_in[3 * b + i], z[b, i])
      np.testing.assert_array_equal(a_in[3 * b + i], action[b, i])


class _FixedGaussian:
  """Stands in for MLPProposal: mean and log-std the same for every latent."""

  def __init__(self, mean, log_std):
    self.mean, self.log_std = jnp.asarray(mean), jnp.asarray(log_std)

  def apply(self, variables, zs):
    shape = zs.shape[:-1] + self.mean.shape
    return jnp.broadcast_to(self.mean, shape), jnp.broadcast_to(self.log_std, shape)


def test_gaussian_step_is_mean_plus_std_noise_clipped():
  model = types.SimpleNamespace(action_dim=2)  # All the kind reads of the model's settings.
  module = _FixedGaussian([0.5, -0.9], np.log([0.1, 2.0]))
  key = jax.random.key(3)
  kind = proposals.PROPOSALS.get('mlp')
  a = kind.make_step(model, None, module)({'proposal': {}}, jnp.zeros((4, 5)), key)
  noise = jax.random.normal(jax.random.split(key)[0], (4, 1, 2))[:, 0]
  np.testing.assert_allclose(a, np.clip(np.array([0.5, -0.9]) + np.array([0.1, 2.0]) * noise,
                                        -1.0, 1.0), rtol=1e-6)
  # As a proposal: `num` draws of one action for one latent, [num, 1, A].
  drawn = kind.make_propose(model, None, module)({'proposal': {}}, jnp.zeros(5), key, 4)
  np.testing.assert_allclose(drawn[:, 0], a, rtol=1e-6)


def test_mlp_proposal_log_std_stays_in_its_bounds():
  module = proposals.MLPProposal(hidden=(), action_dim=2)
  params = module.init(jax.random.key(0), jnp.zeros((1, 3)))
  z = 1e3 * jax.random.normal(jax.random.key(1), (64, 3))  # Saturates the sigmoid both ways.
  mean, log_std = module.apply(params, z)
  assert float(jnp.abs(mean).max()) <= 1.0
  assert float(log_std.min()) >= module.log_std_min and float(log_std.max()) <= module.log_std_max
  assert float(log_std.min()) < module.log_std_min + 0.1
  assert float(log_std.max()) > module.log_std_max - 0.1


def test_single_step_proposal_draws_a_fresh_action_at_every_latent(smoke_config):
  """With a single-step proposal, a_i depends on z_i: different rollouts differ after step 0."""
  config = ablations.with_overrides(smoke_config, ablations.VARIANTS['diffstep_mlp'][1])
  params = models.init_params(config, jax.random.key(0))
  m = ModelSettings.from_config(config)
  rollout = planner.make_rollout(m, PlanSettings.from_config(config), models.build_networks(m))
  actions, latents = rollout(params, jnp.ones(config.model.latent_dim), 3, jax.random.key(1))
  chex.assert_shape(actions, (3, config.horizon, config.action_dim))
  chex.assert_shape(latents, (3, config.horizon + 1, config.model.latent_dim))
  assert float(jnp.abs(actions[0] - actions[1]).max()) > 0
