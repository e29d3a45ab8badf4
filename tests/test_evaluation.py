"""Tests for the evaluation protocol on a tiny fake env, plus one real check."""

import ctypes.util
import os
import warnings

import gymnasium as gym
import jax
import numpy as np
import pytest

from ld_mpc_jax.eval import evaluation, evaluation_suite
from ld_mpc_jax.envs import metaworld_env


class _FakeEnv(gym.Env):
  """Succeeds at decision `seed % 4 + 2` if seed is even, never if odd.

  It never truncates by itself, so the evaluator's step limit is exercised.
  Observations are [decision index]; reward is 1 per decision.
  """
  action_space = gym.spaces.Box(-1, 1, (1,), np.float32)

  def __init__(self, **kwargs):
    self.kwargs = kwargs
    self.episode_seeds = []

  def reset(self, *, seed=None, options=None):
    self.t, self.seed_ = 0, seed
    self.episode_seeds.append(seed)
    return np.zeros(1), {}

  def step(self, action):
    self.t += 1
    success = self.seed_ % 2 == 0 and self.t >= self.seed_ % 4 + 2
    return np.array([self.t]), 1.0, False, False, {'success': success}

  def render(self):
    return np.full((8, 8, 3), 10 * self.t, np.uint8)


def _expected(seed, n, max_decisions):
  seeds = metaworld_env.episode_seeds(seed, n, 'eval')
  lengths = [s % 4 + 2 if s % 2 == 0 else max_decisions for s in seeds]
  return np.array([s % 2 == 0 for s in seeds]), np.array(lengths)


def test_protocol_counts_on_fake_env():
  envs, resets, calls = [], [], []

  def factory(**kwargs):
    envs.append(_FakeEnv(**kwargs))
    return envs[-1]

  def policy(obs):
    calls.append(obs)
    return np.zeros(1)

  res = evaluation.evaluate(policy, 'door-open-v3', num_episodes=20, seed=3,
                            action_repeat=2, max_episode_steps=20,
                            reset=resets.append, env_factory=factory, progress=False)
  success, lengths = _expected(3, 20, max_decisions=10)
  assert 0 < success.sum() < 20  # The seeds give both outcomes.
  assert res['success_rate'] == pytest.approx(success.mean())
  assert res['outcomes'] == success.astype(int).tolist()
  assert res['successes'] == success.sum() and res['episodes'] == 20
  assert res['mean_length'] == pytest.approx(lengths.mean())
  assert res['mean_return'] == pytest.approx(lengths.mean())
  assert len(calls) == lengths.sum() and len(resets) == 20
  assert [ep.index for ep in resets] == list(range(20))
  assert res['num_episodes'] == 20 and res['decisions_per_s'] > 0
  lo, hi = res['success_ci95']
  assert lo <= res['success_rate'] <= hi
  assert envs[0].kwargs['terminate_on_success']
  assert envs[0].kwargs['max_episode_steps'] == 20
  # Per-episode records: the decision of the first success, length, return, seeds.
  seeds = metaworld_env.episode_seeds(3, 20, 'eval')
  for rec, s, ok, n in zip(res['records'], seeds, success, lengths):
    assert rec['reset_seed'] == s and rec['eval_seed'] == 3
    assert rec['success'] == ok and rec['length'] == n and rec['return'] == n
    assert rec['first_success'] == (n if ok else None)
    assert rec['env_steps'] == 2 * n
  # Seeded: the same seed replays the same episodes.
  again = evaluation.evaluate(policy, 'door-open-v3', num_episodes=20, seed=3,
                              max_episode_steps=20, env_factory=factory,
                              progress=False)
  assert again['records'] == res['records']


def test_lockstep_waves_give_the_same_records_as_one_at_a_time():
  episodes = evaluation.seeded_episodes(5, 7)
  policy = evaluation.CallablePolicy(lambda obs: np.zeros(1))
  runs = [evaluation.run_episodes(policy, episodes, 'door-open-v3', batch_size=b,
                                  max_episode_steps=20, env_factory=_FakeEnv,
                                  progress=False)[0] for b in (1, 3, 7)]
  assert runs[0] == runs[1] == runs[2]
  assert len(runs[0]) == 7 and [r['episode'] for r in runs[0]] == list(range(7))
  with pytest.raises(ValueError, match='batch_size'):
    evaluation.run_episodes(policy, episodes, 'door-open-v3', batch_size=0,
                            env_factory=_FakeEnv, progress=False)



class _Bar:
  """Records what run_episodes shows on its progress bar."""
  made = []

  def __init__(self, total, **kwargs):
    self.total, self.n, self.trace, self.postfix = total, 0, [], ''
    _Bar.made.append(self)

  def update(self, k):
    self.n += k
    self.trace.append(self.n)

  def set_postfix_str(self, s):
    self.postfix = s

  def close(self):
    pass


def test_the_progress_bar_counts_lockstep_decisions_and_ends_full(monkeypatch):
  # In lockstep, episodes end together at the limit: a bar over episodes reads 0 until then.
  monkeypatch.setattr(evaluation.tqdm, 'tqdm', _Bar)
  episodes = evaluation.seeded_episodes(5, 7)
  records, _ = evaluation.run_episodes(evaluation.CallablePolicy(lambda obs: np.zeros(1)),
                                       episodes, 'door-open-v3', batch_size=3,
                                       max_episode_steps=20, env_factory=_FakeEnv)
  bar = _Bar.made[-1]
  assert bar.total == 3 * 10  # Three waves of at most 10 decisions.
  assert bar.n == bar.total and bar.trace == sorted(bar.trace)
  assert bar.trace[:3] == [1, 2, 3]  # One tick a decision, from the first.
  solved = sum(r['success'] for r in records)
  assert 0 < solved < 7 and bar.postfix == f'episodes 7/7, solved {solved}'


class _InfoPolicy(evaluation.CallablePolicy):
  """Reports `info` [4] per environment after each decision, as agent.BatchAgentPolicy does."""

  def __init__(self, info):
    super().__init__(lambda obs: np.zeros(1))
    self.info = info

  def __call__(self, obs, t, active):
    self.last_info = np.tile(np.asarray(self.info), (len(obs), 1))
    return np.zeros((len(obs), 1))


def test_departures_are_counted_for_planners_only():
  episodes = evaluation.seeded_episodes(5, 4)
  run = lambda info: evaluation.run_episodes(_InfoPolicy(info), episodes, 'door-open-v3',
                                             batch_size=2, max_episode_steps=20,
                                             env_factory=_FakeEnv, progress=False)[0]
  planner = run((2, 0, 1, -1))  # Every decision departed from the actor prior's sequence.
  assert [r['departures'] for r in planner] == [r['length'] for r in planner]
  assert all('fallback_at' not in r for r in planner)  # No fallback configured.
  assert all(r['departures'] == 0 for r in run((2, 0, 0, -1)))
  assert all('departures' not in r for r in run((-1, 0, 0, -1)))  # A policy that does not plan.


class _FallingPolicy(_InfoPolicy):
  """A planner with the fallback that hands every episode to the actor prior at decision 3."""

  def __call__(self, obs, t, active):
    self.last_info = np.tile(np.asarray((2, 0, int(t < 3), int(t >= 3))), (len(obs), 1))
    return np.zeros((len(obs), 1))


def test_fallback_records_the_first_decision_of_the_actor_prior():
  episodes = evaluation.seeded_episodes(5, 4)
  run = lambda policy: evaluation.run_episodes(policy, episodes, 'door-open-v3', batch_size=2,
                                               max_episode_steps=20, env_factory=_FakeEnv,
                                               progress=False)[0]
  fell = run(_FallingPolicy(None))
  lengths = [r['length'] for r in fell]  # _FakeEnv ends some episodes within three decisions.
  assert [r['fallback_at'] for r in fell] == [3 if n > 3 else None for n in lengths]
  assert [r['departures'] for r in fell] == [min(n, 3) for n in lengths] and max(lengths) > 3
  armed = run(_InfoPolicy((2, 0, 1, 0)))  # Armed, never fallen.
  assert all(r['fallback_at'] is None for r in armed)
  rows = evaluation_suite.against_anchor(
      [dict(r, policy='plan', run=0) for r in fell + armed[:2]], anchor='plan')
  assert rows[0]['fallbacks'] == sum(n > 3 for n in lengths) > 0

def test_noise_sweep_and_fake_video(tmp_path):
  path = str(tmp_path / 'v.gif')
  results = evaluation.noise_sweep(
      lambda o: np.zeros(1), 'door-open-v3', [0.0, 0.05], num_episodes=3,
      max_episode_steps=8, env_factory=_FakeEnv, video_path=path,
      video_episodes=2, progress=False)
  assert [r['obs_noise_std'] for r in results] == [0.0, 0.05]
  assert results[0]['video_path'] == path and os.path.getsize(path) > 0


def test_scripted_policy_on_real_env_is_deterministic():
  policy = evaluation.scripted_policy_with_noise('door-open-v3', 0.0)
  a = evaluation.evaluate(policy, 'door-open-v3', num_episodes=2, seed=0,
                          progress=False)
  b = evaluation.evaluate(policy, 'door-open-v3', num_episodes=2, seed=0,
                          progress=False)
  assert a['records'] == b['records']
  assert 0 < a['mean_length'] <= 250
  assert a['mean_env_steps'] <= 500


@pytest.mark.skipif(
    os.environ.get('MUJOCO_GL') != 'osmesa'
    or ctypes.util.find_library('OSMesa') is None,
    reason='offscreen MuJoCo rendering needs MUJOCO_GL=osmesa set before the '
    'tests start and libosmesa6 (apt-get install -y libosmesa6)')
def test_real_video(tmp_path):
  """An mp4 through imageio-ffmpeg, with JAX's threads running and without a fork warning
  (ffmpeg starts without a Python preexec_fn in the forked child)."""
  jax.block_until_ready(jax.numpy.ones(3) * 2)  # JAX started: its at-fork warning is armed.
  with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter('always')
    res = evaluation.evaluate(
        lambda o: np.zeros(4, np.float32), 'door-open-v3', num_episodes=1,
        max_episode_steps=6, video_path=str(tmp_path / 'v.mp4'), image_size=64,
        progress=False)
  assert not [w for w in caught if 'fork' in str(w.message)], [str(w.message) for w in caught]
  assert res['video_path'] == str(tmp_path / 'v.mp4')  # imageio-ffmpeg: mp4, not a gif.
  assert os.path.getsize(res['video_path']) > 0
  assert 'IMAGEIO_FFMPEG_NO_PREVENT_SIGINT' not in os.environ  # Restored.


def test_env_pool_keeps_the_latest_settings_and_closes_the_rest(monkeypatch):
  """Environments are reused for the same settings; beyond MAX_ENV_POOLS settings the oldest
  pool is closed and dropped (MT10 evaluations held 50 environments of every task before)."""
  monkeypatch.setattr(evaluation, '_ENV_POOL', type(evaluation._ENV_POOL)())
  made = []

  class Env:
    closed = False

    def close(self):
      self.closed = True

  def factory(**kwargs):
    made.append(Env())
    return made[-1]

  first = evaluation._envs(factory, 3, dict(task='a'))
  assert evaluation._envs(factory, 2, dict(task='a')) == first[:2]  # Reused, none built.
  assert len(made) == 3
  for task in 'bcd':
    evaluation._envs(factory, 2, dict(task=task))
  assert len(evaluation._ENV_POOL) == evaluation.MAX_ENV_POOLS == 2
  # a (3 environments) and b (2) closed; c and d (2 each) kept.
  assert [e.closed for e in made] == [True] * 5 + [False] * 4
