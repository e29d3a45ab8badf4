"""ld_mpc_jax.data.collection: scripted episodes with their noise levels, collection metadata, and
the cache of collected datasets."""

import os
import zipfile

import gymnasium as gym
import numpy as np
import pytest

from ld_mpc_jax.data import collection
from ld_mpc_jax.data import dataset as dataset_lib


def _tiny():
  """A dataset of two short episodes (6-d observations, 2-d actions)."""
  rng = np.random.default_rng(0)
  eps = [dict(obs=rng.normal(size=(n + 1, 6)), action=rng.uniform(-1, 1, (n, 2)),
              reward=rng.normal(size=n)) for n in (3, 5)]
  return dataset_lib.Dataset.from_episodes(eps, metadata=dict(obs_dim=6, act_dim=2))


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


def test_get_or_collect_caches_and_moves_bad_files_aside(tmp_path, monkeypatch):
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
  with open(path + '.bad', 'rb') as f:  # Moved aside, not overwritten.
    assert f.read() == b'garbage'
  # A file of an older collector (no version) is collected again; it too is kept.
  monkeypatch.setattr(collection, 'COLLECTOR_VERSION', collection.COLLECTOR_VERSION + 1)
  with pytest.warns(UserWarning, match='collecting again'):
    collection.get_or_collect(**args)
  assert len(calls) == 3
  assert zipfile.is_zipfile(path + '.1.bad') and os.path.exists(path + '.bad')


def test_a_cached_dataset_with_nan_is_moved_aside_not_overwritten(tmp_path, monkeypatch):
  monkeypatch.setattr(collection, 'collect', lambda *a, **k: _tiny())
  path = collection.dataset_path(str(tmp_path), 'door-open-v3', 'expert', 3, 0, 2)
  ds = _tiny()
  ds.observations[0, 0] = np.nan
  monkeypatch.setattr(dataset_lib.Dataset, 'validate', lambda self: None)
  dataset_lib.save(ds, path)  # A damaged file: NaN in the observations.
  monkeypatch.undo()
  monkeypatch.setattr(collection, 'collect', lambda *a, **k: _tiny())
  before = open(path, 'rb').read()
  with pytest.warns(UserWarning) as record:
    collection.get_or_collect('door-open-v3', 'expert', 3, 0, str(tmp_path), action_repeat=2)
  message = str(record[0].message)
  assert message == (f'invalid cached dataset ({path}: observations contains NaN or inf '
                     f'values.): moved to {path}.bad; collecting again')
  assert open(path + '.bad', 'rb').read() == before
