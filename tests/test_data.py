"""Tests for the dataset format, its validation and scripted collection."""

import json
import os
import zipfile

import gymnasium as gym
import numpy as np
import pytest

from ld_mpc_jax.data import collection
from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data.dataset import DatasetError


def _tiny(lengths=(3, 5, 2), obs_dim=6, act_dim=2, seed=0):
  rng = np.random.default_rng(seed)
  eps = [dict(obs=rng.normal(size=(n + 1, obs_dim)),
              action=rng.uniform(-1, 1, (n, act_dim)),
              reward=rng.normal(size=n),
              success=np.arange(n) == n - 1) for n in lengths]
  return dataset_lib.Dataset.from_episodes(
      eps, metadata=dict(task='door-open-v3', obs_dim=obs_dim, act_dim=act_dim,
                         versions={'metaworld': '3.1.1'}),
      episode_data=dict(noise_std=np.array([0.1, 0.2, 0.3])[:len(lengths)]))


def _rewrite(path, **changes):
  """Rewrites a saved dataset with some arrays replaced (no validation)."""
  with np.load(path) as z:
    arrays = {k: z[k] for k in z.files}
  arrays.update(changes)
  np.savez(path, **arrays)


def test_layout_and_round_trip(tmp_path):
  ds = _tiny()
  assert ds.num_episodes == 3 and ds.num_transitions == 10
  np.testing.assert_array_equal(ds.episode_starts, [0, 4, 10])
  assert ds.observations.shape == (13, 6) and ds.actions.shape == (13, 2)
  # The last row of every episode holds no action, reward or success.
  last = ds.episode_starts + ds.episode_lengths
  assert not ds.actions[last].any() and not ds.rewards[last].any()
  assert ds.transition_mask().sum() == 10
  np.testing.assert_array_equal(ds.episode_success(), [True, True, True])
  path = dataset_lib.save(ds, str(tmp_path / 'd.npz'))
  assert os.listdir(tmp_path) == ['d.npz']  # No temp file left behind.
  back = dataset_lib.load(path)
  for name in ('observations', 'actions', 'rewards', 'successes',
               'episode_starts', 'episode_lengths', 'task_ids'):
    np.testing.assert_array_equal(getattr(back, name), getattr(ds, name))
  np.testing.assert_array_equal(back.episode_data['noise_std'], [.1, .2, .3])
  assert back.metadata['task'] == 'door-open-v3'
  assert back.metadata['format_version'] == dataset_lib.FORMAT_VERSION
  ep = back.episode(1)
  assert ep['obs'].shape == (6, 6) and ep['action'].shape == (5, 2)


def test_save_replaces_existing_file_atomically(tmp_path):
  path = str(tmp_path / 'd.npz')
  dataset_lib.save(_tiny(lengths=(2,)), path)
  dataset_lib.save(_tiny(lengths=(4, 4)), path)
  assert dataset_lib.load(path).num_episodes == 2
  assert sorted(os.listdir(tmp_path)) == ['d.npz']


def test_missing_truncated_and_garbage_files(tmp_path):
  with pytest.raises(DatasetError, match='No dataset file'):
    dataset_lib.load(str(tmp_path / 'nope.npz'))
  path = dataset_lib.save(_tiny(), str(tmp_path / 'd.npz'))
  data = open(path, 'rb').read()
  with open(path, 'wb') as f:
    f.write(data[:len(data) // 2])
  with pytest.raises(DatasetError, match='truncated or corrupted'):
    dataset_lib.load(path)
  with open(path, 'wb') as f:
    f.write(b'not a zip file at all')
  with pytest.raises(DatasetError, match='truncated or corrupted'):
    dataset_lib.load(path)
  np.savez(path, observations=np.zeros((2, 3)))
  with pytest.raises(DatasetError, match='missing'):
    dataset_lib.load(path)


@pytest.mark.parametrize('change, message', [
    (dict(actions=np.zeros((13, 2, 1), np.float32)), '2-D'),
    (dict(rewards=np.zeros(12, np.float32)), 'rows'),
    (dict(episode_lengths=np.array([3, 5, 3])), 'boundaries'),
    (dict(episode_starts=np.array([0, 5, 10])), 'boundaries'),
    (dict(task_ids=np.zeros(2, np.int32)), 'vectors'),
])
def test_wrong_shapes_are_rejected(tmp_path, change, message):
  path = dataset_lib.save(_tiny(), str(tmp_path / 'd.npz'))
  _rewrite(path, **change)
  with pytest.raises(DatasetError, match=message):
    dataset_lib.load(path)


def test_nan_and_metadata_dims_are_rejected(tmp_path):
  path = dataset_lib.save(_tiny(), str(tmp_path / 'd.npz'))
  obs = dataset_lib.load(path).observations.copy()
  obs[3, 2] = np.nan
  _rewrite(path, observations=obs)
  with pytest.raises(DatasetError, match='NaN'):
    dataset_lib.load(path)
  path = dataset_lib.save(_tiny(), str(tmp_path / 'd.npz'))
  meta = dataset_lib.load(path).metadata
  _rewrite(path, metadata_json=np.array(json.dumps(dict(meta, obs_dim=39))))
  with pytest.raises(DatasetError, match='obs_dim=39'):
    dataset_lib.load(path)


def test_format_version_mismatch(tmp_path):
  path = dataset_lib.save(_tiny(), str(tmp_path / 'd.npz'))
  meta = dataset_lib.load(path).metadata
  meta['format_version'] = dataset_lib.FORMAT_VERSION + 1
  _rewrite(path, metadata_json=np.array(json.dumps(meta)))
  with pytest.raises(DatasetError, match='format version'):
    dataset_lib.load(path)


def test_metaworld_major_version_mismatch_warns(tmp_path):
  ds = _tiny()
  ds.metadata['versions'] = {'metaworld': '2.0.0'}
  path = dataset_lib.save(ds, str(tmp_path / 'd.npz'))
  with pytest.warns(RuntimeWarning, match='metaworld 2.0.0'):
    dataset_lib.load(path)


def test_from_episodes_rejects_bad_episodes():
  with pytest.raises(DatasetError, match='at least one'):
    dataset_lib.Dataset.from_episodes([])
  bad = dict(obs=np.zeros((3, 4)), action=np.zeros((3, 2)), reward=np.zeros(3))
  with pytest.raises(DatasetError, match=r'obs \[L\+1, d\]'):
    dataset_lib.Dataset.from_episodes([bad])


def test_level_assignment_follows_fractions():
  levels = collection.level_assignment('mixed', 200, seed=0)
  np.testing.assert_array_equal(np.bincount(levels), [50, 50, 50, 50])
  np.testing.assert_array_equal(
      levels, collection.level_assignment('mixed', 200, seed=0))
  assert np.bincount(collection.level_assignment('mixed', 6, 1)).sum() == 6
  with pytest.raises(ValueError, match='preset'):
    collection.level_assignment('bogus', 10, 0)


class _FakeEnv(gym.Env):
  """Succeeds at decision 2 only; truncates after 5 decisions."""
  action_space = gym.spaces.Box(-1, 1, (4,), np.float32)

  def reset(self, *, seed=None, options=None):
    self.t = 0
    return np.zeros(39), {}

  def step(self, action):
    self.t += 1
    info = {'success': self.t == 2}
    return np.full(39, self.t, float), 1.0, False, self.t == 5, info


def test_run_episode_does_not_stop_at_success():
  ep = collection.run_episode(_FakeEnv(), lambda o: np.zeros(4), 0.3, 0.5, 7)
  assert ep['obs'].shape == (6, 39) and ep['action'].shape == (5, 4)
  np.testing.assert_array_equal(ep['success'], [0, 1, 0, 0, 0])
  assert np.all(np.abs(ep['action']) <= 1)
  again = collection.run_episode(_FakeEnv(), lambda o: np.zeros(4), .3, .5, 7)
  np.testing.assert_array_equal(ep['action'], again['action'])


def test_collect_records_metadata():
  ds = collection.collect('door-open-v3', 'mixed', 2, seed=3,
                          max_episode_steps=8, progress=False)
  assert ds.num_episodes == 2
  np.testing.assert_array_equal(ds.episode_lengths, [4, 4])  # 8 steps / 2.
  meta = ds.metadata
  assert meta['task'] == 'door-open-v3' and meta['preset'] == 'mixed'
  assert meta['action_repeat'] == 2 and meta['max_episode_steps'] == 8
  assert set(meta['versions']) >= {'metaworld', 'mujoco', 'numpy'}
  assert set(ds.episode_data) == {'level', 'noise_std', 'random_prob', 'seed'}
  assert ds.observations.shape[1] == 39 and ds.actions.shape[1] == 4


def test_get_or_collect_caches_and_replaces_bad_files(tmp_path, monkeypatch):
  calls = []

  def fake_collect(task, preset, episodes, seed, action_repeat,
                   max_episode_steps, progress):
    calls.append(1)
    ds = _tiny()
    ds.metadata.update(task=task, preset=preset, episodes=episodes, seed=seed,
                       action_repeat=action_repeat,
                       max_episode_steps=max_episode_steps,
                       collector_version=collection.COLLECTOR_VERSION)
    return ds

  monkeypatch.setattr(collection, 'collect', fake_collect)
  args = dict(task='door-open-v3', preset='expert', episodes=3, seed=0,
              data_dir=str(tmp_path), action_repeat=2)
  first = collection.get_or_collect(**args)
  second = collection.get_or_collect(**args)
  assert len(calls) == 1
  np.testing.assert_array_equal(first.observations, second.observations)
  path = collection.dataset_path(str(tmp_path), 'door-open-v3', 'expert', 3,
                                 0, 2)
  with open(path, 'wb') as f:
    f.write(b'garbage')
  with pytest.warns(UserWarning, match='invalid cached dataset'):
    collection.get_or_collect(**args)
  assert len(calls) == 2
  assert zipfile.is_zipfile(path)
  # A file of an older collector (no version) is collected again.
  monkeypatch.setattr(collection, 'COLLECTOR_VERSION', collection.COLLECTOR_VERSION + 1)
  with pytest.warns(UserWarning, match='collecting again'):
    collection.get_or_collect(**args)
  assert len(calls) == 3


def test_data_sources_are_a_registry_with_one_line_errors():
  from experiments.configs import door_open
  from ld_mpc_jax import envs
  from ld_mpc_jax.data import sources
  assert sources.SOURCES.names() == (envs.SUITE.name, 'tdmpc2')
  assert sources.SCRIPTED == envs.SUITE.name
  c = door_open.get_config('smoke')
  c.data.source = 'nosuch'
  with pytest.raises(ValueError, match=r"^config.data.source must be one of 'metaworld', "
                                       r"'tdmpc2', got 'nosuch'$"):
    sources.check_source(c)
  c.data.source = 'tdmpc2'
  with pytest.raises(ValueError, match='needs config.data.path'):
    sources.check_source(c)
