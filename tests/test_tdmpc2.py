"""Tests for the TD-MPC2 offline-data loader (chunks need the [tdmpc2] extra)."""

import importlib.util
import json
import os
import pickle
import subprocess
import sys

import numpy as np
import pytest

from ld_mpc_jax.data import tdmpc2
from ld_mpc_jax.data.dataset import DatasetError

HAVE_EXTRA = all(importlib.util.find_spec(m) is not None
                 for m in ('torch', 'tensordict'))
needs_extra = pytest.mark.skipif(
    not HAVE_EXTRA, reason='torch/tensordict not installed (optional extra: '
    'pip install torch==2.13.0 && pip install -e .[tdmpc2])')

L, D_PAD, A_PAD = 6, 45, 7  # Steps per episode; padded obs/action sizes.
# (task name, true obs dim, true act dim) of the episodes in the chunk.
EPISODES = [('walker-walk', 24, 6), ('mw-door-open', 39, 4), ('mw-reach', 39, 4),
            ('mw-door-open', 39, 4), ('cheetah-run', 17, 6)]


def _chunk_arrays(seed=0):
  """Arrays in TD-MPC2's chunk layout: [N, L, ...], zero-padded, NaN at t=0."""
  rng = np.random.default_rng(seed)
  n = len(EPISODES)
  obs = np.zeros((n, L, D_PAD), np.float32)
  act = np.zeros((n, L, A_PAD), np.float32)
  for i, (_, d, a) in enumerate(EPISODES):
    obs[i, :, :d] = rng.normal(size=(L, d))
    act[i, :, :a] = rng.uniform(-1, 1, (L, a))
  act[:, 0] = np.nan
  rew = rng.normal(size=(n, L)).astype(np.float32)
  rew[:, 0] = np.nan
  task = np.array([tdmpc2.task_index('mt80', t) for t, _, _ in EPISODES])
  return obs, act, rew, np.repeat(task[:, None], L, axis=1)


def _write_chunk(path, obs, act, rew, task):
  import torch  # pylint: disable=g-import-not-at-top
  from tensordict import TensorDict  # pylint: disable=g-import-not-at-top
  td = TensorDict(dict(obs=torch.from_numpy(obs), action=torch.from_numpy(act),
                       reward=torch.from_numpy(rew),
                       task=torch.from_numpy(task)), batch_size=obs.shape[:2])
  torch.save(td, path)
  return str(path)


def test_task_lists():
  assert len(tdmpc2.TASK_SETS['mt30']) == 30
  assert len(tdmpc2.TASK_SETS['mt80']) == 80
  assert len(set(tdmpc2.TASK_SETS['mt80'])) == 80
  assert tdmpc2.task_index('mt80', 'mw-door-open') == 41
  assert tdmpc2.task_index('mt80', 'walker-stand') == 0
  assert tdmpc2.task_index('mt80', 'mw-hand-insert') == 79
  assert tdmpc2.TASK_SETS['mt80'][:30] == tdmpc2.TASK_SETS['mt30']
  with pytest.raises(ValueError, match='not in TD-MPC2 mt30'):
    tdmpc2.task_index('mt30', 'mw-door-open')
  with pytest.raises(ValueError, match='task set'):
    tdmpc2.task_index('mt50', 'mw-door-open')
  assert tdmpc2.true_dims('mw-door-open') == (39, 4)
  with pytest.raises(ValueError, match='dims='):
    tdmpc2.true_dims('walker-walk')


def test_missing_extra_gives_install_hint(monkeypatch, tmp_path):
  monkeypatch.setitem(sys.modules, 'torch', None)
  with pytest.raises(ImportError, match=r'pip install -e \.\[tdmpc2\]'):
    tdmpc2.load_tdmpc2(str(tmp_path), 'mt80', ['mw-door-open'])


@needs_extra
def test_selects_unpads_reindexes_and_realigns(tmp_path):
  obs, act, rew, task = _chunk_arrays()
  _write_chunk(tmp_path / 'chunk_0.pt', obs, act, rew, task)
  ds = tdmpc2.load_tdmpc2(str(tmp_path), 'mt80', ['mw-reach', 'mw-door-open'])
  kept = [2, 1, 3]  # Rows of the chunk with the selected tasks, file order.
  assert ds.num_episodes == 3 and ds.obs_dim == 39 and ds.act_dim == 4
  np.testing.assert_array_equal(ds.task_ids, [1, 0, 1])  # door=1, reach=0.
  assert ds.metadata['original_task_ids'] == [
      tdmpc2.task_index('mt80', 'mw-reach'), 41]
  np.testing.assert_array_equal(ds.episode_lengths, [L - 1] * 3)
  for e, row in enumerate(sorted(kept)):
    ep = ds.episode(e)
    np.testing.assert_array_equal(ep['obs'], obs[row, :, :39])
    # Our action[t] is TD-MPC2's action[t + 1] (the one that led to obs[t+1]).
    np.testing.assert_array_equal(ep['action'], act[row, 1:, :4])
    np.testing.assert_array_equal(ep['reward'], rew[row, 1:])
  assert not ds.successes.any() and not ds.metadata['successes_recorded']


@needs_extra
def test_mixed_dims_and_errors(tmp_path):
  obs, act, rew, task = _chunk_arrays()
  path = _write_chunk(tmp_path / 'c.pt', obs, act, rew, task)
  ds = tdmpc2.load_tdmpc2(path, 'mt80', ['cheetah-run', 'walker-walk'],
                          dims={'cheetah-run': (17, 6), 'walker-walk': (24, 6)})
  assert ds.obs_dim == 24 and ds.act_dim == 6
  np.testing.assert_array_equal(ds.task_ids, [1, 0])
  with pytest.raises(DatasetError, match='non-zero values beyond'):
    tdmpc2.load_tdmpc2(path, 'mt80', ['walker-walk'],
                       dims={'walker-walk': (20, 6)})
  with pytest.raises(DatasetError, match='No episodes'):
    tdmpc2.load_tdmpc2(path, 'mt80', ['mw-sweep'])
  obs[1, 3, 5] = np.nan
  path = _write_chunk(tmp_path / 'c.pt', obs, act, rew, task)
  with pytest.raises(DatasetError, match='NaN'):
    tdmpc2.load_tdmpc2(path, 'mt80', ['mw-door-open'])
  with open(tmp_path / 'bad.pt', 'wb') as f:
    f.write(b'garbage')
  with pytest.raises(DatasetError, match='Cannot read'):
    tdmpc2.load_tdmpc2(str(tmp_path / 'bad.pt'), 'mt80', ['mw-door-open'])


# ---------------------------------------------------------------------------------------------
# TD-MPC2 data in the main job (config.data.source = 'tdmpc2'), with or without torch: a stand-in
# torch module reads chunks written as pickled dicts of numpy arrays, so the whole path from the
# config to a trained, evaluated checkpoint runs here; only torch's own unpickling is not tested.

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FAKE_TORCH = '''"""Test stand-in for torch: load() reads a pickled dict of numpy arrays."""
import pickle


class Tensor:  # Other libraries (tensorboardX) probe torch.Tensor when torch imports.
  def __init__(self, array):
    self._array = array

  def detach(self):
    return self

  def cpu(self):
    return self

  def numpy(self):
    return self._array


def load(path, map_location=None, weights_only=None):
  with open(path, 'rb') as f:
    return {k: Tensor(v) for k, v in pickle.load(f).items()}
'''
MT80_L = 13  # Observations per synthetic episode (mt80's real episodes have 101).


@pytest.fixture
def fake_torch(tmp_path, monkeypatch):
  """Directory holding stand-in torch / tensordict modules, importable in this process."""
  path = tmp_path / 'fake_torch'
  path.mkdir()
  (path / 'torch.py').write_text(FAKE_TORCH)
  (path / 'tensordict.py').write_text('"""Test stand-in: imported, never used."""\n')
  for name in ('torch', 'tensordict'):
    monkeypatch.delitem(sys.modules, name, raising=False)
  monkeypatch.syspath_prepend(str(path))
  return str(path)


def _mt80_chunk(path, tasks, seed=0):
  """Writes a synthetic mt80 chunk of one episode per task name, as fake torch reads it.

  Returns obs [N, L, 39] (the true sizes of the Meta-World episodes).
  """
  rng = np.random.default_rng(seed)
  n = len(tasks)
  obs = np.zeros((n, MT80_L, 39 + 6), np.float32)  # Padded like the real files.
  obs[..., :39] = rng.normal(size=(n, MT80_L, 39))
  act = np.zeros((n, MT80_L, 4 + 2), np.float32)
  act[..., :4] = rng.uniform(-1, 1, (n, MT80_L, 4))
  act[:, 0] = np.nan
  rew = rng.uniform(0, 10, (n, MT80_L)).astype(np.float32)
  rew[:, 0] = np.nan
  task = np.repeat(np.array([tdmpc2.task_index('mt80', t) for t in tasks])[:, None], MT80_L, 1)
  with open(path, 'wb') as f:
    pickle.dump(dict(obs=obs, action=act, reward=rew, task=task), f)
  return obs[..., :39]


def test_v3_names_map_to_tdmpc2_and_back():
  assert tdmpc2.tdmpc2_task_name('door-open-v3') == 'mw-door-open'
  assert tdmpc2.tdmpc2_task_name('peg-insert-side-v3') == 'mw-peg-insert-side'
  assert tdmpc2.v3_task_name('mw-pick-out-of-hole') == 'pick-out-of-hole-v3'
  from ld_mpc_jax.envs.metaworld_env import task_names
  assert sorted(tdmpc2.v3_task_name(t) for t in tdmpc2.TASK_SETS['mt80'][30:]) == task_names()
  for bad in ('door-open-v2', 'walker-walk', 'mw-door-open'):
    with pytest.raises(ValueError, match='TD-MPC2 mt80'):
      tdmpc2.tdmpc2_task_name(bad)
  with pytest.raises(ValueError, match='50 Meta-World tasks'):
    tdmpc2.v3_task_name('walker-walk')


def test_source_config_errors(fake_torch, tmp_path, smoke_config):
  from ld_mpc_jax.config_checks import validate_config
  from ld_mpc_jax.data import sources
  c = smoke_config
  c.data.source = 'd4rl'
  with pytest.raises(ValueError, match="config.data.source must be one of 'metaworld', 'tdmpc2', got 'd4rl'"):
    validate_config(c)
  c.data.source = 'tdmpc2'
  with pytest.raises(ValueError, match='needs config.data.path'):
    validate_config(c)
  obs = _mt80_chunk(tmp_path / 'chunk_0.pt', ['mw-door-open', 'mw-reach', 'mw-door-open'])
  _mt80_chunk(tmp_path / 'chunk_1.pt', ['mw-door-open'], seed=1)
  c.data.path = str(tmp_path / 'chunk_*.pt')  # A glob pattern: both chunks.
  validate_config(c)
  ds = sources.load_for_config(c)
  assert ds.num_episodes == 3 and (ds.obs_dim, ds.act_dim) == (39, 4)
  np.testing.assert_array_equal(ds.episode(1)['obs'], obs[2])
  c.task = 'drawer-open-v3'  # In TD-MPC2's list, not in these files.
  with pytest.raises(DatasetError, match=r"config.task='drawer-open-v3' \(TD-MPC2 "
                     r"'mw-drawer-open'\): No episodes"):
    sources.load_for_config(c)
  c.task, c.obs_dim = 'door-open-v3', 40
  with pytest.raises(DatasetError, match=r'sizes \(39, 4\), but config.obs_dim/action_dim are '
                     r'\(40, 4\)'):
    sources.load_for_config(c)
  c.obs_dim, c.data.path = 39, str(tmp_path / 'none_*.pt')
  with pytest.raises(DatasetError, match='No TD-MPC2 chunk files'):
    sources.load_for_config(c)


@pytest.mark.long
def test_train_from_tdmpc2_chunks_end_to_end(fake_torch, tmp_path):
  from ld_mpc_jax import checkpointing
  chunk = tmp_path / 'chunks'
  chunk.mkdir()
  obs = _mt80_chunk(chunk / 'chunk_0.pt', ['mw-door-open', 'mw-reach', 'mw-door-open'])
  workdir = str(tmp_path / 'run')
  cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open.py:smoke',
         f'--workdir={workdir}', '--config.data.source=tdmpc2',
         f'--config.data.path={chunk}/chunk_*.pt', '--config.task=door-open-v3']
  env = dict(os.environ, PYTHONPATH=os.pathsep.join([fake_torch, REPO]))
  done = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  with open(os.path.join(workdir, 'report.json')) as f:
    report = json.load(f)
  assert report['steps'] == 4 and report['task'] == 'door-open-v3'
  assert report['dataset']['source'] == 'tdmpc2' and report['dataset']['episodes'] == 2
  assert report['dataset']['transitions'] == 2 * (MT80_L - 1)
  # Held-out goals only: TD-MPC2's goals were random per episode, there is no train split.
  assert list(report['evaluation']) == ['held_out']
  assert 0.0 <= report['success_rate'] <= 1.0
  # The normalisation in the checkpoint is that of the two door-open episodes of the chunk.
  config, params, step = checkpointing.load_for_evaluation(workdir)
  assert step == 4 and config.data.source == 'tdmpc2'
  np.testing.assert_allclose(params['encoder']['obs_mean'], obs[[0, 2]].reshape(-1, 39).mean(0),
                             rtol=1e-4, atol=1e-5)
  # A task the files do not hold: one line and exit code 2.
  cmd[-1] = '--config.task=drawer-open-v3'
  bad = subprocess.run(cmd + [f'--workdir={tmp_path / "bad"}'], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=300)
  assert bad.returncode == 2, bad.stderr[-2000:]
  assert bad.stderr.strip().splitlines()[-1].startswith('error: config.data.path=')
  assert 'No episodes' in bad.stderr


@needs_extra
def test_real_torch_chunk_trains(tmp_path):
  """The same run from a chunk written by torch.save (needs the [tdmpc2] extra)."""
  rng = np.random.default_rng(0)
  obs = rng.normal(size=(2, MT80_L, 39)).astype(np.float32)
  act = rng.uniform(-1, 1, (2, MT80_L, 4)).astype(np.float32)
  act[:, 0] = np.nan
  rew = rng.uniform(0, 10, (2, MT80_L)).astype(np.float32)
  rew[:, 0] = np.nan
  task = np.full((2, MT80_L), tdmpc2.task_index('mt80', 'mw-door-open'))
  _write_chunk(tmp_path / 'chunk_0.pt', obs, act, rew, task)
  workdir = str(tmp_path / 'run')
  cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open.py:smoke',
         f'--workdir={workdir}', '--config.data.source=tdmpc2',
         f'--config.data.path={tmp_path}/chunk_*.pt', '--config.eval.episodes=0']
  done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  with open(os.path.join(workdir, 'report.json')) as f:
    report = json.load(f)
  assert report['steps'] == 4 and report['dataset']['episodes'] == 2
