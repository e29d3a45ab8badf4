"""Tests for the TD-MPC2 offline-data loader (chunks need the [tdmpc2] extra). (Configs with
TD-MPC2 data: tests/test_sources.py; training from them: tests/e2e/test_tdmpc2_runs.py.)"""

import sys

import numpy as np
import pytest

from ld_mpc_jax.data import tdmpc2
from ld_mpc_jax.data.dataset import DatasetError
from tests.tdmpc2_chunks import needs_extra, write_chunk

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
  (tmp_path / 'chunk_0.pt').write_bytes(b'a chunk file')
  with pytest.raises(ImportError, match=r'pip install -e \.\[tdmpc2\]') as err:
    tdmpc2.load_tdmpc2(str(tmp_path), 'mt80', ['mw-door-open'])
  assert isinstance(err.value, DatasetError)  # One line from the launcher, exit code 2.
  assert '\n' not in str(err.value) and err.value.__cause__ is None


@pytest.mark.parametrize('path', ['missing.pt', 'missing_dir'])
def test_a_missing_path_is_reported_before_torch_is_imported(monkeypatch, tmp_path, path):
  monkeypatch.setitem(sys.modules, 'torch', None)  # Importing it would raise ImportError.
  with pytest.raises(DatasetError, match=r'^No TD-MPC2 chunk file .*missing.*: no such file'):
    tdmpc2.load_tdmpc2(str(tmp_path / path), 'mt80', ['mw-door-open'])


@needs_extra
def test_selects_unpads_reindexes_and_realigns(tmp_path):
  obs, act, rew, task = _chunk_arrays()
  write_chunk(tmp_path / 'chunk_0.pt', obs, act, rew, task)
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
  path = write_chunk(tmp_path / 'c.pt', obs, act, rew, task)
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
  path = write_chunk(tmp_path / 'c.pt', obs, act, rew, task)
  with pytest.raises(DatasetError, match='NaN'):
    tdmpc2.load_tdmpc2(path, 'mt80', ['mw-door-open'])
  with open(tmp_path / 'bad.pt', 'wb') as f:
    f.write(b'garbage')
  with pytest.raises(DatasetError, match='Cannot read'):
    tdmpc2.load_tdmpc2(str(tmp_path / 'bad.pt'), 'mt80', ['mw-door-open'])


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


class _Payload:
  """Unpickling it would call os.system: what a malicious chunk file does."""

  def __init__(self, marker):
    self.marker = marker

  def __reduce__(self):
    import os  # pylint: disable=g-import-not-at-top
    return (os.system, (f'touch {self.marker}',))


def test_chunks_are_unpickled_without_running_code(tmp_path):
  """SafePickle: a file naming os.system is refused on one line and nothing runs; numpy arrays
  and collections load as with pickle; the allowlist takes classes and rebuild functions only."""
  import io
  import pickle
  marker = tmp_path / 'ran'
  with pytest.raises(pickle.UnpicklingError, match='refused to load (posix|os).system'):
    tdmpc2.SafePickle.load(io.BytesIO(pickle.dumps({'obs': _Payload(marker)})))
  assert not marker.exists()
  import collections
  data = collections.OrderedDict(obs=np.arange(6.0).reshape(2, 3), task={1, 2})
  back = tdmpc2.SafePickle.load(io.BytesIO(pickle.dumps(data)))
  np.testing.assert_array_equal(back["obs"], data["obs"])
  assert back["task"] == {1, 2}
  allowed = tdmpc2.SafePickle.allowed
  assert allowed('collections', 'OrderedDict') and allowed('numpy', 'ndarray')
  assert not allowed('builtins', 'eval') and not allowed('numpy', 'load')  # Functions: no.
  assert not allowed('subprocess', 'Popen') and not allowed('numpy', 'no_such_name')


def _global_call(module, name, arg, opcode='stack'):
  """A hand-written pickle that looks up `module`/`name` and calls it with one string: what a
  crafted file can do that `pickle.dumps` never writes (e.g. a dotted name through a module)."""
  def text(s):
    b = s.encode()
    return b'\x8c' + bytes([len(b)]) + b  # SHORT_BINUNICODE.
  if opcode == 'stack':  # Protocol 4: STACK_GLOBAL resolves dotted names attribute by attribute.
    head = b'\x80\x04' + text(module) + text(name) + b'\x93'
  else:  # Protocol 0's GLOBAL.
    head = b'c' + module.encode() + b'\n' + name.encode() + b'\n'
  return head + text(arg) + b'\x85R.'  # TUPLE1, REDUCE, STOP.


@pytest.mark.parametrize('module,name,opcode', [
    ('numpy.f2py', 'os.system', 'stack'),  # Issue 102: a module's attribute path to os.system.
    ('numpy', 'os.system', 'stack'),
    ('collections', 'os.system', 'stack'),
    ('torch._utils', '_rebuild_tensor_v2.__globals__', 'stack'),
    ('os', 'system', 'global'),
    ('posix', 'system', 'stack'),
    ('builtins', 'eval', 'global'),
    ('builtins', 'getattr', 'stack'),
    ('builtins', '__import__', 'stack'),
    ('numpy', 'load', 'stack'),
    ('numpy.f2py', 'compile', 'stack'),
    ('subprocess', 'Popen', 'stack'),
    ('numpy.testing', 'os', 'stack'),
])
def test_crafted_globals_are_refused_before_anything_runs(tmp_path, module, name, opcode):
  """Every global outside the exact allowlist is refused at lookup, so its call never happens."""
  import io
  import pickle
  marker = tmp_path / 'ran'
  data = _global_call(module, name, f'touch {marker}', opcode)
  with pytest.raises(pickle.UnpicklingError, match='refused to load'):
    tdmpc2.SafePickle.load(io.BytesIO(data))
  assert not marker.exists()
  assert not tdmpc2.SafePickle.allowed(module, name)


def test_a_nested_payload_is_refused_and_the_plain_pickle_would_have_run_it(tmp_path):
  """The payload deep inside lists and dicts is refused too; plain pickle on the same bytes runs
  it (so the test would see a loader that does not restrict)."""
  import io
  import pickle
  marker = tmp_path / 'ran'
  data = pickle.dumps({'obs': [np.zeros(2), {'inner': (_Payload(marker),)}]}, protocol=4)
  with pytest.raises(pickle.UnpicklingError, match='refused to load'):
    tdmpc2.SafePickle.load(io.BytesIO(data))
  assert not marker.exists()
  crafted = _global_call('numpy.f2py', 'os.system', f'touch {marker}')
  pickle.loads(crafted)  # The unrestricted unpickler runs the crafted file's command.
  assert marker.exists()


def test_the_allowlist_is_exact_pairs():
  """No prefix rule: every allowed pair is a module and a plain name; near misses are refused."""
  allowed = tdmpc2.SafePickle.allowed
  for module, name in tdmpc2.SafePickle.ALLOWED:
    assert '.' not in name and module.split('.')[0] in (
        'torch', 'tensordict', 'numpy', 'collections', 'builtins')
  assert allowed('torch._utils', '_rebuild_tensor_v2') and allowed('torch', 'float32')
  assert not allowed('torch._utils', '_rebuild_tensor_v9') and not allowed('torch', 'load')
  assert not allowed('numpy.core.multiarray', 'fromfile')


def test_a_malicious_chunk_fails_in_one_line_through_the_loader(tmp_path, monkeypatch):
  """The loader's torch.load gets SafePickle (here the test stand-in for torch reads through
  it as torch does): DatasetError naming the file, and the payload never runs."""
  import pickle
  from tests.tdmpc2_chunks import FAKE_TORCH
  (tmp_path / 'torch.py').write_text(FAKE_TORCH)
  (tmp_path / 'tensordict.py').write_text('')
  monkeypatch.syspath_prepend(str(tmp_path))
  for name in ('torch', 'tensordict'):
    monkeypatch.delitem(sys.modules, name, raising=False)
  marker = tmp_path / 'ran'
  chunk = tmp_path / 'chunk_0.pt'
  with open(chunk, 'wb') as f:
    pickle.dump({'obs': _Payload(marker)}, f)
  with pytest.raises(DatasetError, match='refused to load'):
    tdmpc2.load_tdmpc2(str(chunk), 'mt80', ['mw-door-open'])
  assert not marker.exists()
