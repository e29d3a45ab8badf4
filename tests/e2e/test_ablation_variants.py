"""End to end: every ablation variant (experiments.train ablations) builds, trains one step and plans."""

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.cli import ablations
from ld_mpc_jax.model import models
from ld_mpc_jax.plan import planner
from ld_mpc_jax.learn.train_state import LearnSettings, create_train_state, make_update


def _batch(config):
  """The preset's batch shape: the default variant's update is then the one other tests compile."""
  b, h, rng = config.train.batch_size, config.horizon, np.random.default_rng(0)
  return {'obs': jnp.asarray(rng.normal(size=(b, h + 2, config.obs_dim)), jnp.float32),
          'action': jnp.asarray(rng.uniform(-1, 1, size=(b, h + 2 - 1, config.action_dim)),
                                jnp.float32),
          'reward': jnp.asarray(rng.uniform(0, 1, size=(b, h + 1)), jnp.float32)}


@pytest.mark.long
@pytest.mark.parametrize('name', list(ablations.VARIANTS))
def test_variant_builds_trains_one_step_and_plans(smoke_config, name):
  config = ablations.with_overrides(smoke_config, ablations.VARIANTS[name][1])
  learn = LearnSettings.from_config(config)
  state = create_train_state(learn, jax.random.key(0))
  before = jax.tree_util.tree_map(np.array, state.params)  # Host copies: the update donates.
  state, metrics = make_update(learn)(state, _batch(config), jax.random.key(1))
  assert np.isfinite(float(metrics['loss']))
  after = jax.device_get(state.params)
  for net in ('proposal', 'dynamics'):  # Both kinds of network receive gradients.
    moved = jax.tree_util.tree_map(lambda a, b: float(np.abs(a - b).max()), before[net],
                                   after[net])
    assert max(jax.tree_util.tree_leaves(moved)) > 0, net
  z = models.encode(state.params, jnp.linspace(-1, 1, config.obs_dim))
  out = planner.make_plan(config)(state.params, z, jax.random.key(2))
  k, h, a = config.plan.num_candidates, config.horizon, config.action_dim
  chex.assert_shape(out.candidates, (k, h, a))
  chex.assert_shape(out.action, (a,))
  assert np.all(np.abs(np.asarray(out.candidates)) <= 1.0)
  assert np.all(np.isfinite(np.asarray(out.scores)))
  np.testing.assert_allclose(out.action, out.candidates[int(out.index), 0])
