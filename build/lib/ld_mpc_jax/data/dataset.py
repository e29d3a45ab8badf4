"""Offline datasets: one flat layout, one validated on-disk file (.npz).

Layout (E episodes, episode e has L_e >= 1 transitions and L_e + 1
observations; N = sum_e (L_e + 1) rows):

  observations    float32 [N, obs_dim]  row i: what the agent saw before acting.
  actions         float32 [N, act_dim]  row i: the action taken after row i's
                                        observation; zeros on each episode's
                                        last row (there is no action there).
  rewards         float32 [N]           reward that followed actions[i]; 0 on
                                        the last row of an episode.
  successes       bool    [N]           info['success'] after actions[i]; False
                                        on the last row of an episode.
  episode_starts  int64   [E]           first row of each episode.
  episode_lengths int64   [E]           L_e (transitions); the episode occupies
                                        rows starts[e] .. starts[e] + L_e.
  task_ids        int32   [E]           task index of each episode (0 for a
                                        single task).
  episode_data    dict of [E] arrays    per-episode extras (noise std, seed).
  metadata        JSON-able dict        task, preset, versions, ...

Episodes are stored back to back: starts[0] = 0 and
starts[e + 1] = starts[e] + L_e + 1. A length-T window starting at row s lies
inside episode e iff starts[e] <= s and s + T - 1 <= starts[e] + L_e.

File: a single uncompressed .npz holding the arrays above under the same names,
`episode_data` arrays as `episode_data/<name>`, and the metadata as a JSON
string under `metadata_json`. It is written atomically (temp file + rename) and
validated on load (`DatasetError` on anything wrong).
"""

import dataclasses
from importlib import metadata as importlib_metadata
import json
import os
import tempfile
import warnings
import zipfile
from typing import Any, Dict, Mapping, Optional, Sequence

import numpy as np

from ld_mpc_jax import envs

FORMAT_VERSION = 1
_ARRAYS = ('observations', 'actions', 'rewards', 'successes',
           'episode_starts', 'episode_lengths', 'task_ids')


class DatasetError(ValueError):
  """A dataset file or array set is missing, corrupted or inconsistent."""


@dataclasses.dataclass
class Dataset:
  """Episodes in the flat layout of the module docstring."""
  observations: np.ndarray
  actions: np.ndarray
  rewards: np.ndarray
  successes: np.ndarray
  episode_starts: np.ndarray
  episode_lengths: np.ndarray
  task_ids: np.ndarray
  episode_data: Dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
  metadata: Dict[str, Any] = dataclasses.field(default_factory=dict)

  @property
  def num_episodes(self) -> int:
    return int(self.episode_starts.shape[0])

  @property
  def num_transitions(self) -> int:
    return int(self.episode_lengths.sum())

  @property
  def obs_dim(self) -> int:
    return int(self.observations.shape[1])

  @property
  def act_dim(self) -> int:
    return int(self.actions.shape[1])

  def episode(self, e: int) -> Dict[str, np.ndarray]:
    """Episode e: obs [L+1, obs_dim], action [L, act_dim], reward [L], success [L]."""
    s, n = int(self.episode_starts[e]), int(self.episode_lengths[e])
    return dict(obs=self.observations[s:s + n + 1],
                action=self.actions[s:s + n],
                reward=self.rewards[s:s + n],
                success=self.successes[s:s + n])

  def episode_success(self) -> np.ndarray:
    """bool [E]: success was reached at some step of the episode."""
    return np.logical_or.reduceat(self.successes, self.episode_starts)

  def episode_returns(self) -> np.ndarray:
    """float64 [E]: sum of rewards per episode (last rows hold 0)."""
    return np.add.reduceat(self.rewards.astype(np.float64),
                           self.episode_starts)

  def transition_mask(self) -> np.ndarray:
    """bool [N]: True on rows that hold a real (obs, action, reward) step."""
    mask = np.ones(self.observations.shape[0], dtype=bool)
    mask[self.episode_starts + self.episode_lengths] = False
    return mask

  def validate(self) -> 'Dataset':
    """Checks shapes, dtypes, boundaries and finiteness; raises DatasetError."""
    validate_arrays(self)
    return self

  @classmethod
  def from_episodes(cls, episodes: Sequence[Mapping[str, np.ndarray]],
                    metadata: Optional[Dict[str, Any]] = None,
                    task_ids: Optional[Sequence[int]] = None,
                    episode_data: Optional[Dict[str, np.ndarray]] = None
                    ) -> 'Dataset':
    """Builds a dataset from per-episode dicts.

    Args:
      episodes: each has obs [L+1, obs_dim], action [L, act_dim], reward [L]
        and optionally success [L].
      metadata: JSON-able dict stored with the data.
      task_ids: [E] task index per episode (default zeros).
      episode_data: per-episode arrays, each [E].

    Returns:
      A validated Dataset.
    """
    if not episodes:
      raise DatasetError('A dataset needs at least one episode.')
    lengths = np.array([len(ep['action']) for ep in episodes], dtype=np.int64)
    obs, act, rew, suc = [], [], [], []
    for ep, n in zip(episodes, lengths):
      o = np.asarray(ep['obs'], dtype=np.float32)
      a = np.asarray(ep['action'], dtype=np.float32)
      if o.ndim != 2 or a.ndim != 2 or o.shape[0] != n + 1:
        raise DatasetError(
            f'Episode needs obs [L+1, d] and action [L, a]; got obs '
            f'{o.shape} and action {a.shape}.')
      obs.append(o)
      act.append(np.concatenate([a, np.zeros((1, a.shape[1]), np.float32)]))
      rew.append(np.append(np.asarray(ep['reward'], np.float32), 0.0))
      s = ep.get('success', np.zeros(n, bool))
      suc.append(np.append(np.asarray(s, bool), False))
    starts = np.concatenate([[0], np.cumsum(lengths + 1)[:-1]]).astype(np.int64)
    ids = np.zeros(len(episodes), np.int32) if task_ids is None else (
        np.asarray(task_ids, np.int32))
    return cls(observations=np.concatenate(obs), actions=np.concatenate(act),
               rewards=np.concatenate(rew).astype(np.float32),
               successes=np.concatenate(suc), episode_starts=starts,
               episode_lengths=lengths, task_ids=ids,
               episode_data={k: np.asarray(v)
                             for k, v in (episode_data or {}).items()},
               metadata=dict(metadata or {})).validate()


def validate_arrays(ds: Dataset) -> None:
  """Raises DatasetError unless `ds` follows the module docstring's layout."""
  obs, act = ds.observations, ds.actions
  if obs.ndim != 2 or act.ndim != 2:
    raise DatasetError(f'observations and actions must be 2-D, got shapes '
                       f'{obs.shape} and {act.shape}.')
  n = obs.shape[0]
  for name in ('actions', 'rewards', 'successes'):
    if getattr(ds, name).shape[0] != n:
      raise DatasetError(f'{name} has {getattr(ds, name).shape[0]} rows but '
                         f'observations has {n}.')
  if ds.rewards.ndim != 1 or ds.successes.ndim != 1:
    raise DatasetError(f'rewards and successes must be [N], got '
                       f'{ds.rewards.shape} and {ds.successes.shape}.')
  e = ds.episode_starts.shape
  if (ds.episode_starts.ndim != 1 or ds.episode_lengths.shape != e
      or ds.task_ids.shape != e or e[0] == 0):
    raise DatasetError(
        f'episode_starts, episode_lengths and task_ids must be equal [E>0] '
        f'vectors, got {ds.episode_starts.shape}, {ds.episode_lengths.shape}, '
        f'{ds.task_ids.shape}.')
  lengths = ds.episode_lengths.astype(np.int64)
  if np.any(lengths < 1):
    raise DatasetError('Every episode needs at least one transition.')
  expected = np.concatenate([[0], np.cumsum(lengths + 1)[:-1]])
  if (not np.array_equal(ds.episode_starts, expected)
      or int(np.sum(lengths + 1)) != n):
    raise DatasetError(
        'Episode boundaries are inconsistent: episodes must be stored back to '
        'back with L+1 rows each and cover all observation rows.')
  for k, v in ds.episode_data.items():
    if np.shape(v)[:1] != e:
      raise DatasetError(f'episode_data[{k!r}] must have {e[0]} rows, got '
                         f'shape {np.shape(v)}.')
  for name in ('observations', 'actions', 'rewards'):
    if not np.all(np.isfinite(getattr(ds, name))):
      raise DatasetError(f'{name} contains NaN or inf values.')
  if not ds.metadata.get('obs_dim', obs.shape[1]) == obs.shape[1]:
    raise DatasetError(f'metadata says obs_dim={ds.metadata["obs_dim"]} but '
                       f'observations are {obs.shape[1]}-dimensional.')
  if not ds.metadata.get('act_dim', act.shape[1]) == act.shape[1]:
    raise DatasetError(f'metadata says act_dim={ds.metadata["act_dim"]} but '
                       f'actions are {act.shape[1]}-dimensional.')


def save(ds: Dataset, path: str) -> str:
  """Validates `ds` and writes it to `path` (.npz) atomically; returns path."""
  ds.validate()
  path = os.fspath(path)
  directory = os.path.dirname(os.path.abspath(path))
  os.makedirs(directory, exist_ok=True)
  meta = dict(ds.metadata)
  meta['format_version'] = FORMAT_VERSION
  arrays = {name: getattr(ds, name) for name in _ARRAYS}
  arrays.update({f'episode_data/{k}': v for k, v in ds.episode_data.items()})
  arrays['metadata_json'] = np.array(json.dumps(meta, sort_keys=True))
  fd, tmp = tempfile.mkstemp(dir=directory, suffix='.npz.tmp')
  try:
    with os.fdopen(fd, 'wb') as f:
      np.savez(f, **arrays)
      f.flush()
      os.fsync(f.fileno())
    os.replace(tmp, path)
  except BaseException:
    if os.path.exists(tmp):
      os.remove(tmp)
    raise
  return path


def load(path: str) -> Dataset:
  """Reads and validates a dataset file written by `save`.

  Raises:
    DatasetError: missing, truncated or corrupted file, missing arrays, wrong
      shapes, NaN/inf values, or a different format version. A different
      MAJOR version of the environment suite's package only warns
      (RuntimeWarning): the data stay readable but may not match the installed
      simulator.
  """
  path = os.fspath(path)
  if not os.path.isfile(path):
    raise DatasetError(f'No dataset file at {path}.')
  try:
    with np.load(path, allow_pickle=False) as z:
      files = set(z.files)
      missing = [k for k in _ARRAYS + ('metadata_json',) if k not in files]
      if missing:
        raise DatasetError(f'{path} is not a dataset file: missing {missing}.')
      meta = json.loads(str(z['metadata_json']))
      arrays = {k: z[k] for k in _ARRAYS}
      extras = {k.split('/', 1)[1]: z[k] for k in files
                if k.startswith('episode_data/')}
  except DatasetError:
    raise
  except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError,
          json.JSONDecodeError) as err:
    raise DatasetError(
        f'{path} is truncated or corrupted ({type(err).__name__}: {err}). '
        'Delete it and collect again.') from err
  version = meta.get('format_version')
  if version != FORMAT_VERSION:
    raise DatasetError(
        f'{path} has dataset format version {version}, this code reads '
        f'version {FORMAT_VERSION}. Collect the data again.')
  _check_suite_version(meta, path)
  ds = Dataset(metadata=meta, episode_data=extras, **arrays)
  try:
    ds.validate()
  except DatasetError as err:
    raise DatasetError(f'{path}: {err}') from err
  return ds


def package_versions() -> Dict[str, Optional[str]]:
  """Installed versions of the packages that shape collected data."""
  out = {}
  for name in envs.SUITE.packages + ('numpy', 'gymnasium'):
    try:
      out[name] = importlib_metadata.version(name)
    except importlib_metadata.PackageNotFoundError:
      out[name] = None
  return out


def _major(version: Optional[str]) -> Optional[str]:
  return None if not version else str(version).split('.')[0]


def _check_suite_version(meta: Mapping[str, Any], path: str) -> None:
  package = envs.SUITE.packages[0]
  recorded = meta.get('versions', {}).get(package)
  if recorded is None:
    return
  installed = package_versions().get(package)
  if installed and _major(installed) != _major(recorded):
    warnings.warn(
        f'{path} was collected with {package} {recorded} but {package} '
        f'{installed} is installed (different major version): simulator and '
        'rewards may differ from the data.', RuntimeWarning, stacklevel=3)
