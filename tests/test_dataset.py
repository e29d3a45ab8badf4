"""ld_mpc_jax.data.dataset: the dataset format, its files and their validation."""

import json
import os

import numpy as np
import pytest

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
