"""Loader for TD-MPC2's published multi-task offline datasets (mt30 / mt80).

Each chunk file (`*.pt`) is a TensorDict saved with `torch.save`, with batch
size [num_episodes, L] (L = 101 for mt80, 501 for mt30) and keys

  obs     [N, L, D_max]  observations, zero-padded to the largest task's size;
  action  [N, L, A_max]  action that LED TO obs[:, t] (NaN at t = 0), padded;
  reward  [N, L]         reward of that action (NaN at t = 0);
  task    [N, L]         index into TD-MPC2's task list (TASK_SETS below).

`load_tdmpc2` keeps the episodes of the tasks named by the caller, strips the
zero padding down to those tasks' true sizes (Meta-World: 39 / 4), re-indexes
the kept tasks 0..K-1 in the caller's order, and re-aligns steps to this
project's convention (actions[i] is taken after observations[i]): each episode
gives L observations and L - 1 transitions. Success flags are not stored in
these files, so `successes` is all False (metadata: successes_recorded=False).

torch and tensordict are an optional extra (`pip install -e .[tdmpc2]`, with
the CPU wheel `pip install torch==2.13.0`); they are imported only here, once
the chunk files are found.

Safety: TensorDicts do not load with `weights_only=True`, not even with
tensordict's classes allowlisted (pytorch/tensordict#1363), so chunk files are
read by torch's full unpickler with a restricted `find_class` (`SafePickle`, the
"restricting globals" recipe of Python's pickle docs): a file may name only the
exact fully-qualified names in `SafePickle.ALLOWED` (tensor, storage and dtype
classes, TensorDict, numpy's array pickling and the tensor-rebuilding
functions), never anything else: no prefix or module-wide rule, no dotted
attribute path (`numpy.f2py` + `os.system` reached os.system through a module's
attribute before), no module is even imported unless the pair is listed. A
malicious file is refused on one line instead of run. The CI machine has no
torch; with torch 2.13.0 and tensordict 0.15.3 installed, tests/test_tdmpc2.py
passes whole (real chunks written by torch.save), and TensorDicts of float32,
float16 and bfloat16, nested, consolidated and in torch's legacy format load
(2026-12-06). A chunk that names another global fails on one line naming it.
"""

import glob
import os
import pickle
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from ld_mpc_jax.data import dataset as dataset_lib

_DMC = [
    # 19 original DMControl tasks.
    'walker-stand', 'walker-walk', 'walker-run', 'cheetah-run', 'reacher-easy',
    'reacher-hard', 'acrobot-swingup', 'pendulum-swingup', 'cartpole-balance',
    'cartpole-balance-sparse', 'cartpole-swingup', 'cartpole-swingup-sparse',
    'cup-catch', 'finger-spin', 'finger-turn-easy', 'finger-turn-hard',
    'fish-swim', 'hopper-stand', 'hopper-hop',
    # 11 custom DMControl tasks.
    'walker-walk-backwards', 'walker-run-backwards', 'cheetah-run-backwards',
    'cheetah-run-front', 'cheetah-run-back', 'cheetah-jump',
    'hopper-hop-backwards', 'reacher-three-easy', 'reacher-three-hard',
    'cup-spin', 'pendulum-spin',
]
_MW50 = [
    'mw-assembly', 'mw-basketball', 'mw-button-press-topdown',
    'mw-button-press-topdown-wall', 'mw-button-press', 'mw-button-press-wall',
    'mw-coffee-button', 'mw-coffee-pull', 'mw-coffee-push', 'mw-dial-turn',
    'mw-disassemble', 'mw-door-open', 'mw-door-close', 'mw-drawer-close',
    'mw-drawer-open', 'mw-faucet-open', 'mw-faucet-close', 'mw-hammer',
    'mw-handle-press-side', 'mw-handle-press', 'mw-handle-pull-side',
    'mw-handle-pull', 'mw-lever-pull', 'mw-peg-insert-side',
    'mw-peg-unplug-side', 'mw-pick-out-of-hole', 'mw-pick-place',
    'mw-pick-place-wall', 'mw-plate-slide', 'mw-plate-slide-side',
    'mw-plate-slide-back', 'mw-plate-slide-back-side', 'mw-push-back',
    'mw-push', 'mw-push-wall', 'mw-reach', 'mw-reach-wall', 'mw-shelf-place',
    'mw-soccer', 'mw-stick-push', 'mw-stick-pull', 'mw-sweep-into', 'mw-sweep',
    'mw-window-open', 'mw-window-close', 'mw-bin-picking', 'mw-box-close',
    'mw-door-lock', 'mw-door-unlock', 'mw-hand-insert',
]
# TD-MPC2's task lists (tdmpc2/common/__init__.py, TASK_SET), in index order.
TASK_SETS: Dict[str, List[str]] = {'mt30': list(_DMC), 'mt80': _DMC + _MW50}
# True (obs_dim, act_dim) of task families whose sizes are fixed.
_KNOWN_DIMS = {'mw-': (39, 4)}

_INSTALL_HINT = (
    'Loading TD-MPC2 datasets needs the optional extra: pip install -e '
    '.[tdmpc2] (install torch first as the CPU wheel: pip install '
    'torch==2.13.0).')


class MissingExtraError(dataset_lib.DatasetError, ImportError):
  """torch or tensordict is not installed (one line saying how to install them)."""


_TORCH_DTYPES = ('float16', 'float32', 'float64', 'bfloat16', 'half', 'float', 'double',
                 'complex64', 'complex128', 'uint8', 'int8', 'int16', 'int32', 'int64',
                 'short', 'int', 'long', 'bool')
_TORCH_STORAGES = ('UntypedStorage', 'DoubleStorage', 'FloatStorage', 'HalfStorage',
                   'BFloat16Storage', 'LongStorage', 'IntStorage', 'ShortStorage',
                   'CharStorage', 'ByteStorage', 'BoolStorage', 'ComplexFloatStorage',
                   'ComplexDoubleStorage')
_TENSORDICTS = ('TensorDict', 'LazyStackedTensorDict')
# Names that older tensordicts pickled (<= 0.4, as TD-MPC2's chunks may be) and that newer ones
# read as plain types, as tensordict's own weights-only allowlist does.
_RENAMED = {('tensordict.utils', '_StringOnlyDict'): dict}


class _RestrictedUnpickler(pickle.Unpickler):
  """pickle.Unpickler whose globals are limited to `SafePickle.allowed`."""

  def find_class(self, module, name):
    if (module, name) in _RENAMED:
      return _RENAMED[module, name]
    if not SafePickle.allowed(module, name):
      raise pickle.UnpicklingError(f'refused to load {module}.{name}: a TD-MPC2 chunk holds '
                                   'tensors only (the file may run code)')
    return super().find_class(module, name)


class SafePickle:
  """A pickle module for `torch.load(pickle_module=...)` that refuses every global but the exact
  (module, name) pairs of `ALLOWED`."""
  Unpickler = _RestrictedUnpickler
  __name__ = 'SafePickle'
  # Every global a TD-MPC2 chunk (a TensorDict of tensors, via torch.save) or a pickled numpy
  # array may name, fully qualified; nothing else is ever looked up.
  ALLOWED = frozenset(
      [('torch', n) for n in _TORCH_DTYPES + _TORCH_STORAGES + ('Size', 'device', 'Tensor')]
      + [('torch.storage', n) for n in ('UntypedStorage', 'TypedStorage', '_load_from_bytes')]
      + [('torch._utils', n) for n in ('_rebuild_tensor', '_rebuild_tensor_v2',
                                       '_rebuild_tensor_v3', '_rebuild_parameter')]
      + [('torch._tensor', '_rebuild_from_type_v2'), ('torch.serialization', '_get_layout')]
      + [(m, n) for m in ('tensordict', 'tensordict._td', 'tensordict.tensordict',
                          'tensordict._lazy') for n in _TENSORDICTS]
      + [('tensordict._reductions', n) for n in ('_make_td', '_rebuild_tensordict_files',
                                                 '_rebuild_tensordict_files_consolidated')]
      + [(m, n) for m in ('numpy.core.multiarray', 'numpy._core.multiarray')
         for n in ('_reconstruct', 'scalar')]
      + [('numpy', 'ndarray'), ('numpy', 'dtype'), ('collections', 'OrderedDict')]
      + [('builtins', n) for n in ('set', 'frozenset', 'slice', 'complex')]
      + [('numpy.dtypes', n) for n in ('Float32DType', 'Float64DType', 'Int64DType',
                                       'Int32DType', 'BoolDType', 'UInt8DType')])

  @staticmethod
  def allowed(module: str, name: str) -> bool:
    """Whether a file may name `module.name`: an exact listed pair, never a dotted path."""
    return (module, name) in SafePickle.ALLOWED

  @staticmethod
  def load(file, **kwargs):
    return _RestrictedUnpickler(file, **kwargs).load()


def _import_torch():
  try:
    import tensordict  # pylint: disable=g-import-not-at-top,unused-import
    import torch  # pylint: disable=g-import-not-at-top
  except ImportError as err:
    raise MissingExtraError(f'{_INSTALL_HINT} ({err})') from None
  return torch


def task_index(task_set: str, task: str) -> int:
  """Index of `task` (e.g. 'mw-door-open') in TD-MPC2's `task_set` list."""
  if task_set not in TASK_SETS:
    raise ValueError(f'Unknown TD-MPC2 task set {task_set!r}; valid: '
                     f'{sorted(TASK_SETS)}.')
  names = TASK_SETS[task_set]
  if task not in names:
    raise ValueError(f'{task!r} is not in TD-MPC2 {task_set}; valid names: '
                     + ', '.join(names))
  return names.index(task)


def true_dims(task: str, dims: Optional[Dict[str, Tuple[int, int]]] = None
              ) -> Tuple[int, int]:
  """(obs_dim, act_dim) of `task`: from `dims`, else known families (mw-*)."""
  if dims and task in dims:
    return tuple(int(d) for d in dims[task])
  for prefix, value in _KNOWN_DIMS.items():
    if task.startswith(prefix):
      return value
  raise ValueError(f'True observation/action sizes of {task!r} are not known; '
                   f'pass dims={{{task!r}: (obs_dim, act_dim)}}.')


def tdmpc2_task_name(task: str) -> str:
  """TD-MPC2's name of a Meta-World v3 task: 'door-open-v3' -> 'mw-door-open'.

  TD-MPC2's data were collected on the Meta-World v2 version of the same task.
  """
  name = 'mw-' + task[:-len('-v3')] if task.endswith('-v3') else None
  if name not in _MW50:
    raise ValueError(f'{task!r} is not a Meta-World v3 task that TD-MPC2 mt80 has; TD-MPC2 '
                     "names map as 'mw-door-open' <-> 'door-open-v3'.")
  return name


def v3_task_name(task: str) -> str:
  """This project's (v3) name of a TD-MPC2 Meta-World task: 'mw-door-open' -> 'door-open-v3'."""
  if task not in _MW50:
    raise ValueError(f'{task!r} is not one of TD-MPC2\'s 50 Meta-World tasks (mw-*).')
  return task[len('mw-'):] + '-v3'


def _chunk_files(paths: Union[str, Sequence[str]]) -> List[str]:
  if isinstance(paths, (str, os.PathLike)):
    paths = [os.fspath(paths)]
  files = []
  for p in paths:
    if any(c in p for c in '*?['):  # A glob pattern such as 'chunks/chunk_*.pt'.
      files.extend(sorted(glob.glob(p)))
    else:
      if not os.path.exists(p):
        raise dataset_lib.DatasetError(f'No TD-MPC2 chunk file {p}: no such file or folder.')
      files.extend(sorted(glob.glob(os.path.join(p, '*.pt')))
                   if os.path.isdir(p) else [p])
  if not files:
    raise dataset_lib.DatasetError(f'No TD-MPC2 chunk files (*.pt) in {paths}.')
  return files


def _to_numpy(td, key: str, path: str) -> np.ndarray:
  try:
    return td[key].detach().cpu().numpy()
  except KeyError as err:
    raise dataset_lib.DatasetError(
        f'{path} has no {key!r} entry; not a TD-MPC2 chunk.') from err


def load_tdmpc2(paths: Union[str, Sequence[str]], task_set: str,
                tasks: Sequence[str],
                dims: Optional[Dict[str, Tuple[int, int]]] = None
                ) -> dataset_lib.Dataset:
  """Loads the episodes of `tasks` from TD-MPC2 chunk files.

  Args:
    paths: a chunk file, a glob pattern of chunk files, a directory of `*.pt` chunks, or a
      list of these.
    task_set: 'mt30' or 'mt80' (which task list the files index into).
    tasks: TD-MPC2 task names to keep, e.g. ['mw-door-open']; kept task k gets
      task id k.
    dims: optional {task: (obs_dim, act_dim)} for tasks outside Meta-World.

  Returns:
    A Dataset with obs [N, max obs_dim of kept tasks] and actions
    [N, max act_dim], task_ids [E] in 0..len(tasks)-1.

  Raises:
    MissingExtraError (a DatasetError and an ImportError): torch/tensordict
      missing (one line saying how to install), raised only once the files are found.
    ValueError: unknown task set or task name.
    DatasetError: unreadable chunk, non-zero padding, NaNs, no episodes.
  """
  if not tasks:
    raise ValueError('Select at least one task by name.')
  original = [task_index(task_set, t) for t in tasks]
  if len(set(original)) != len(original):
    raise ValueError(f'Duplicate task names in {list(tasks)}.')
  sizes = [true_dims(t, dims) for t in tasks]
  obs_dim = max(s[0] for s in sizes)
  act_dim = max(s[1] for s in sizes)
  remap = {orig: new for new, orig in enumerate(original)}
  chunks = _chunk_files(paths)  # Before torch: a wrong path is reported without the extra.
  torch = _import_torch()
  obs_parts, act_parts, rew_parts, ids, files = [], [], [], [], []
  for path in chunks:
    part = _read_chunk(torch, path, original, obs_dim, act_dim)
    if part is None:
      continue
    files.append(path)
    obs_parts.append(part[0])
    act_parts.append(part[1])
    rew_parts.append(part[2])
    ids.append(np.array([remap[t] for t in part[3]], np.int32))
  if not ids:
    raise dataset_lib.DatasetError(
        f'No episodes of {list(tasks)} in the given TD-MPC2 files.')
  return _to_dataset(np.concatenate(obs_parts), np.concatenate(act_parts),
                     np.concatenate(rew_parts), np.concatenate(ids),
                     dict(source='tdmpc2', task_set=task_set,
                          tasks=list(tasks), original_task_ids=original,
                          obs_dim=obs_dim, act_dim=act_dim,
                          task_dims=[list(s) for s in sizes],
                          successes_recorded=False, files=files))


def _read_chunk(torch, path: str, original: Sequence[int], obs_dim: int, act_dim: int):
  """One chunk's episodes of the `original` task ids: (obs [n, L, obs_dim], act [n, L, act_dim],
  rew [n, L], task ids [n]) cut to the true sizes, or None when it holds none of them."""
  try:  # Torch's unpickler with globals restricted (module docstring): no code runs.
    td = torch.load(path, map_location='cpu', weights_only=False, pickle_module=SafePickle)
  except Exception as err:  # pylint: disable=broad-except
    raise dataset_lib.DatasetError(
        f'Cannot read TD-MPC2 chunk {path}: {err}') from err
  obs, act = _to_numpy(td, 'obs', path), _to_numpy(td, 'action', path)
  rew, task = _to_numpy(td, 'reward', path), _to_numpy(td, 'task', path)
  if obs.ndim != 3 or act.ndim != 3 or obs.shape[:2] != act.shape[:2]:
    raise dataset_lib.DatasetError(
        f'{path}: expected obs [N, L, D] and action [N, L, A], got '
        f'{obs.shape} and {act.shape}.')
  task = task.reshape(obs.shape[0], -1)[:, 0].astype(np.int64)
  keep = np.isin(task, original)
  if not keep.any():
    return None
  obs, act, rew = obs[keep], act[keep], rew.reshape(keep.size, -1)[keep]
  if obs.shape[2] < obs_dim or act.shape[2] < act_dim:
    raise dataset_lib.DatasetError(
        f'{path}: padded sizes {obs.shape[2]}/{act.shape[2]} are smaller '
        f'than the true sizes {obs_dim}/{act_dim}.')
  for name, arr, d in (('obs', obs, obs_dim), ('action', act[:, 1:], act_dim)):
    if np.any(arr[..., d:] != 0):
      raise dataset_lib.DatasetError(
          f'{path}: {name} has non-zero values beyond dimension {d}; the '
          'true sizes given for these tasks look wrong.')
  return obs[..., :obs_dim], act[..., :act_dim], rew, task[keep]


def _to_dataset(obs: np.ndarray, act: np.ndarray, rew: np.ndarray,
                ids: np.ndarray, metadata: Dict) -> dataset_lib.Dataset:
  """obs [N, L, D], act [N, L, A] (act[:, 0] unused), rew [N, L] -> Dataset."""
  n, length = obs.shape[:2]
  actions = np.zeros_like(act, dtype=np.float32)
  actions[:, :-1] = act[:, 1:]
  rewards = np.zeros((n, length), np.float32)
  rewards[:, :-1] = rew[:, 1:]
  ds = dataset_lib.Dataset(
      observations=obs.reshape(n * length, -1).astype(np.float32),
      actions=actions.reshape(n * length, -1),
      rewards=rewards.reshape(-1),
      successes=np.zeros(n * length, bool),
      episode_starts=np.arange(n, dtype=np.int64) * length,
      episode_lengths=np.full(n, length - 1, np.int64),
      task_ids=ids.astype(np.int32), metadata=metadata)
  try:
    return ds.validate()
  except dataset_lib.DatasetError as err:
    raise dataset_lib.DatasetError(f'TD-MPC2 data: {err}') from err
