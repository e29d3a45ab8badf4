"""ld_mpc_jax.envs.suite and its registry: Meta-World is the one suite registered, and its parts
work together."""

import pytest

from ld_mpc_jax import envs
from ld_mpc_jax.envs import goals


def test_meta_world_is_the_registered_suite():
  assert envs.SUITES.names() == ('metaworld',) and envs.SUITES.get('metaworld') is envs.SUITE
  suite = envs.SUITE
  assert (suite.obs_dim, suite.act_dim, suite.max_episode_steps) == (39, 4, 500)
  assert 'door-open-v3' in suite.task_names() and suite.goal_splits == goals.SPLITS
  env = suite.make_env('door-open-v3', seed=0, max_episode_steps=4)
  obs, _ = env.reset(seed=1)
  assert obs.shape == (suite.obs_dim,)
  assert suite.scripted_policy('door-open-v3')(obs).shape == (suite.act_dim,)
  with pytest.raises(ValueError, match=r"^environment suite must be one of 'metaworld', got "
                                       r"'nosuch'$"):
    envs.SUITES.get('nosuch')
