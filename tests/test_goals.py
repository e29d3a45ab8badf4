"""Goal splits: held-out goals are absent from the data, train goals are the data's own, and an
episode's start is reproducible from its goal and seed."""

import metaworld
import numpy as np
import pytest

from ld_mpc_jax.data import collection
from ld_mpc_jax.envs import goals, metaworld_env


@pytest.fixture(scope='module')
def tiny_dataset():
  return collection.collect('door-open-v3', 'expert', 4, seed=0, max_episode_steps=6,
                            progress=False)


def _starts(episodes):
  env = metaworld_env.make_env('door-open-v3', seed=0)
  return np.stack([env.reset(seed=ep.reset_seed, options={'goal': ep.goal})[1]['goal_vector']
                   for ep in episodes])


def test_held_out_goals_share_no_goal_vector_with_the_dataset(tiny_dataset):
  data_vectors = goals.dataset_goal_vectors(tiny_dataset)
  for seed in (0, 1):
    episodes = goals.make_episodes('door-open-v3', 'held_out', seed, 6, data_vectors, 0)
    starts = _starts(episodes)  # Where the episodes really start, read off the environment.
    dist = np.abs(starts[:, None, :3] - data_vectors[None, :, :3]).max(-1)  # Object position.
    assert dist.min() > 1e-3
    dist = np.abs(starts[:, None, 3:] - data_vectors[None, :, 3:]).max(-1)  # Goal position.
    assert dist.min() > 1e-3
    assert [ep.goal_id for ep in episodes] == [goals.goal_id(v) for v in starts]
    assert len({ep.goal_id for ep in episodes}) == 6  # Different goals, not one repeated.


def test_train_goals_are_the_datasets_own(tiny_dataset):
  data_vectors = goals.dataset_goal_vectors(tiny_dataset)
  episodes = goals.make_episodes('door-open-v3', 'train', 0, 8, data_vectors, 0)
  starts = _starts(episodes)
  assert goals.matches(starts, data_vectors, tol=1e-5).all()
  distinct = {goals.goal_id(v) for v in data_vectors}
  assert {ep.goal_id for ep in episodes} <= distinct
  # 8 episodes cycle through the data's (at most 4) goals.
  assert len({ep.goal_id for ep in episodes}) == len(distinct)
  with pytest.raises(ValueError, match='MT1 seed'):
    goals.make_episodes('door-open-v3', 'train', 0, 2, data_vectors, None)
  with pytest.raises(ValueError, match='unknown goal split'):
    goals.make_episodes('door-open-v3', 'test', 0, 2, data_vectors, 0)


@pytest.mark.parametrize('task', ['door-open-v3', 'pick-place-v3', 'push-v3'])
def test_episode_start_depends_only_on_goal_and_seed(task):
  """Not on numpy's global random state, nor on the episode before."""
  goal = metaworld.MT1(task, seed=3).train_tasks[7]
  env = metaworld_env.make_env(task, seed=0, obs_noise_std=0.01)
  np.random.seed(1)
  first, _ = env.reset(seed=11, options={'goal': goal})
  policy = metaworld_env.scripted_policy(task)
  obs = first
  for _ in range(30):  # Move the objects.
    obs, *_ = env.step(policy(obs))
  np.random.seed(2)
  again, _ = env.reset(seed=11, options={'goal': goal})
  fresh, _ = metaworld_env.make_env(task, seed=5, obs_noise_std=0.01).reset(
      seed=11, options={'goal': goal})
  np.testing.assert_array_equal(first, again)
  np.testing.assert_array_equal(first, fresh)


def test_scripted_policies_leave_the_observation_alone():
  for task in ('door-open-v3', 'button-press-v3'):
    env = metaworld_env.make_env(task, seed=0)
    obs, _ = env.reset(seed=0)
    kept = obs.copy()
    metaworld_env.scripted_policy(task)(obs)
    np.testing.assert_array_equal(obs, kept)
