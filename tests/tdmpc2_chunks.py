"""TD-MPC2 chunk files for the tests (tests/test_tdmpc2.py, tests/test_sources.py and
tests/e2e/test_tdmpc2_runs.py).

With the [tdmpc2] extra, `write_chunk` saves one with torch. Without it, a stand-in torch module
(the `fake_torch` fixture) reads chunks written as pickled dicts of numpy arrays
(`write_mt80_chunk`), so the whole path from a config to a trained, evaluated checkpoint runs
here; only torch's own unpickling is not tested.
"""

import importlib.util
import pickle
import sys

import numpy as np
import pytest

from ld_mpc_jax.data import tdmpc2

HAVE_EXTRA = all(importlib.util.find_spec(m) is not None
                 for m in ('torch', 'tensordict'))
needs_extra = pytest.mark.skipif(
    not HAVE_EXTRA, reason='torch/tensordict not installed (optional extra: '
    'pip install torch==2.13.0 && pip install -e .[tdmpc2])')


def write_chunk(path, obs, act, rew, task):
  """A chunk file as TD-MPC2 saved it: a TensorDict of [N, L, ...] tensors (torch.save)."""
  import torch  # pylint: disable=g-import-not-at-top
  from tensordict import TensorDict  # pylint: disable=g-import-not-at-top
  td = TensorDict(dict(obs=torch.from_numpy(obs), action=torch.from_numpy(act),
                       reward=torch.from_numpy(rew),
                       task=torch.from_numpy(task)), batch_size=obs.shape[:2])
  torch.save(td, path)
  return str(path)


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


def load(path, map_location=None, weights_only=None, pickle_module=pickle):
  with open(path, 'rb') as f:  # Through pickle_module, as torch.load reads its pickle.
    return {k: Tensor(v) for k, v in pickle_module.load(f).items()}
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


def write_mt80_chunk(path, tasks, seed=0):
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
