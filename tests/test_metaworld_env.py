"""ld_mpc_jax.envs.metaworld_env: factory, action repeat, limits, success, noise."""

import gymnasium as gym
import metaworld
import numpy as np
import pytest

from ld_mpc_jax.envs import goals, metaworld_env


class _SuccessAtEnv(gym.Env):
  """Counts steps; reports success only at step `success_step` (1-based)."""
  observation_space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float64)
  action_space = gym.spaces.Box(-1, 1, (4,), np.float32)

  def __init__(self, success_step):
    self.success_step = success_step
    self.max_path_length = 500
    self.t = 0

  def seed(self, seed):
    self.seeded = seed

  def reset(self, *, seed=None, options=None):
    self.t = 0
    return np.zeros(3), {}

  def step(self, action):
    self.t += 1
    info = {'success': float(self.t == self.success_step)}
    return np.full(3, float(self.t)), 1.0, False, False, info


def test_unknown_task_lists_valid_names():
  with pytest.raises(ValueError, match='door-open-v3') as err:
    metaworld_env.make_env('door-opn-v3', seed=0)
  assert 'Unknown Meta-World task' in str(err.value)
  assert len(metaworld_env.task_names()) == 50


def test_episode_limit_counts_environment_steps():
  env = metaworld_env.make_env('door-open-v3', seed=0, action_repeat=3,
                               max_episode_steps=10)
  env.reset(seed=1)
  substeps, truncated, decisions = [], False, 0
  while not truncated:
    _, _, terminated, truncated, info = env.step(np.zeros(4))
    substeps.append(info['substeps'])
    decisions += 1
    assert not terminated
  assert substeps == [3, 3, 3, 1]
  assert info['env_steps'] == 10
  with pytest.raises(RuntimeError):
    env.step(np.zeros(4))


def test_action_repeat_sums_rewards_of_substeps():
  rng = np.random.default_rng(0)
  actions = rng.uniform(-1, 1, (6, 4)).astype(np.float32)
  env2 = metaworld_env.make_env('door-open-v3', seed=0, action_repeat=2)
  env1 = metaworld_env.make_env('door-open-v3', seed=0, action_repeat=1)
  o2, _ = env2.reset(seed=3)
  o1, _ = env1.reset(seed=3)
  np.testing.assert_array_equal(o1, o2)
  for a in actions:
    o2, r2, *_ = env2.step(a)
    r1 = env1.step(a)[1] + env1.step(a)[1]
    assert r2 == pytest.approx(r1, rel=1e-6, abs=1e-9)


def test_max_episode_steps_beyond_metaworld_limit():
  env = metaworld_env.make_env('door-open-v3', seed=0, action_repeat=1,
                               max_episode_steps=503)
  env.reset(seed=0)
  for _ in range(502):
    _, _, _, truncated, _ = env.step(np.zeros(4))
    assert not truncated
  assert env.step(np.zeros(4))[3]


@pytest.mark.parametrize('terminate', [False, True])
def test_success_reported_if_reached_at_any_substep(terminate):
  # Success only at environment step 3 = first sub-step of decision 2.
  env = metaworld_env.MetaWorldWrapper(_SuccessAtEnv(3), seed=0,
                                       action_repeat=2,
                                       terminate_on_success=terminate)
  env.reset()
  _, r, term, _, info = env.step(np.zeros(4))
  assert not info['success'] and not term and r == 2.0
  _, r, term, _, info = env.step(np.zeros(4))
  assert info['success']
  if terminate:
    assert term and info['substeps'] == 1 and r == 1.0
  else:
    assert not term and info['substeps'] == 2 and r == 2.0
    _, _, _, _, info = env.step(np.zeros(4))
    assert not info['success']


def test_seeded_resets_and_observation_noise():
  clean = metaworld_env.make_env('door-open-v3', seed=0)
  noisy = metaworld_env.make_env('door-open-v3', seed=0, obs_noise_std=0.1)
  o_clean, _ = clean.reset(seed=11)
  o_a, _ = noisy.reset(seed=11)
  o_b, _ = noisy.reset(seed=11)
  np.testing.assert_array_equal(o_a, o_b)  # Same seed, same noise.
  diff = o_a - o_clean
  assert 0.05 < diff.std() < 0.2
  o_other, _ = clean.reset(seed=12)
  assert not np.allclose(o_other, o_clean)  # Another goal configuration.
  assert clean.reset(seed=11)[0].tolist() == o_clean.tolist()


def test_random_goals_draw_fresh_seeded_configurations():
  """random_goals (online.train_goals='random'): each reset without a goal draws a configuration
  outside the 50 of the MT1 seed, the same one again for the same reset seed; a given goal still
  sets that goal."""
  env = metaworld_env.make_env('reach-v3', seed=0, random_goals=True)
  fixed = metaworld_env.make_env('reach-v3', seed=0)
  _, mt1 = goals.mt1_goals('reach-v3', 0)
  drawn = np.stack([env.reset(seed=s)[1]['goal_vector'] for s in (1, 2, 1)])
  np.testing.assert_array_equal(drawn[0], drawn[2])
  assert np.abs(drawn[0] - drawn[1]).max() > 0.01
  assert not goals.matches(drawn, mt1).any()
  assert goals.matches(np.stack([fixed.reset(seed=s)[1]['goal_vector'] for s in (1, 2)]),
                       mt1).all()
  task = metaworld_env.mt1_tasks('reach-v3', 0)[3]
  np.testing.assert_allclose(env.reset(seed=5, options={'goal': task})[1]['goal_vector'], mt1[3])
  np.testing.assert_array_equal(env.reset(seed=1)[1]['goal_vector'], drawn[0])


def test_episode_seed_streams_differ():
  a = metaworld_env.episode_seeds(0, 5, 'eval')
  b = metaworld_env.episode_seeds(0, 5, 'collect')
  assert len(set(a) | set(b)) == 10
  np.testing.assert_array_equal(a, metaworld_env.episode_seeds(0, 5, 'eval'))


def test_scripted_policy_action_shape():
  env = metaworld_env.make_env('door-open-v3', seed=0)
  obs, _ = env.reset(seed=0)
  action = metaworld_env.scripted_policy('door-open-v3')(obs)
  assert action.shape == (4,) and action.dtype == np.float32


def test_make_env_matches_metaworlds_own_factory():
  """The cached goal configurations give the environment gym.make('Meta-World/MT1') gives."""
  ours = metaworld_env.make_env('reach-v3', seed=5)
  theirs = metaworld_env.MetaWorldWrapper(
      gym.make('Meta-World/MT1', env_name='reach-v3', seed=5, disable_env_checker=True), seed=5)
  actions = np.random.default_rng(0).uniform(-1, 1, (6, 4)).astype(np.float32)
  for reset_seed in (None, 3, 4):
    a, _ = ours.reset(seed=reset_seed)
    b, _ = theirs.reset(seed=reset_seed)
    np.testing.assert_array_equal(a, b)
    for action in actions:
      a, ra, *_ = ours.step(action)
      b, rb, *_ = theirs.step(action)
      np.testing.assert_array_equal(a, b)
      assert ra == rb
  again = metaworld_env.make_env('reach-v3', seed=5)  # Reuses the cached goals.
  assert again.reset(seed=3)[0].tolist() == ours.reset(seed=3)[0].tolist()
  assert metaworld_env.mt1_tasks('reach-v3', 5)[0].data == (
      metaworld.MT1('reach-v3', seed=5).train_tasks[0].data)
