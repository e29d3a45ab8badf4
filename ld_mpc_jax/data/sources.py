"""The training data a config names: the suite's scripted episodes or TD-MPC2's chunk files.

`config.data.source` picks an entry of the registry `SOURCES`:
* `SCRIPTED` (the environment suite's name, `envs.SUITE.name`): episodes of the suite's scripted
  policies on `config.task`, collected once and cached under `config.data.dir`
  (`collection.get_or_collect`);
* 'tdmpc2': the `config.task` episodes of TD-MPC2's mt80 chunk files at `config.data.path` (a file,
  a glob pattern or a directory). TD-MPC2 recorded Meta-World v2; its 'mw-door-open' is this
  project's 'door-open-v3' (`tdmpc2.tdmpc2_task_name`).
A multi-task config (`config.tasks`) gets every task's scripted dataset joined, with each
episode's task index (`load_multitask`).
"""

import dataclasses
import functools
from typing import Callable

import ml_collections

from ld_mpc_jax import envs
from ld_mpc_jax.envs import tasks
from ld_mpc_jax.data import collection
from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data import multitask, pixels
from ld_mpc_jax.data import tdmpc2
from ld_mpc_jax.ops.registry import Registry

TDMPC2_TASK_SET = 'mt80'  # The only TD-MPC2 task set with Meta-World tasks.


@dataclasses.dataclass(frozen=True)
class Source:
  """A kind of training data: `check(config)` (no file access; one-line ValueError) and
  `load(config, progress)` -> Dataset of config.task."""
  check: Callable[[ml_collections.ConfigDict], None]
  load: Callable[[ml_collections.ConfigDict, bool], dataset_lib.Dataset]


SOURCES = Registry('data source', 'config.data.source')


def _check_scripted(config: ml_collections.ConfigDict) -> None:
  collection.check_preset(config.data.preset, 'config.data.preset')


def _load_scripted(config: ml_collections.ConfigDict, progress: bool) -> dataset_lib.Dataset:
  """The collected episodes; for a model of images, those episodes rendered (data.pixels)."""
  d, a = config.data, config.eval.action_repeat
  ds = collection.get_or_collect(config.task, d.preset, d.episodes, d.seed, d.dir,
                                 action_repeat=a, max_episode_steps=d.max_episode_steps,
                                 progress=progress)
  m = config.model
  if not (m.encoder_type == 'conv' or m.dynamics_type == 'conv_frames'):  # ModelSettings.images
    return ds
  path = collection.dataset_path(d.dir, config.task, d.preset, d.episodes, d.seed, a,
                                 d.max_episode_steps)
  return pixels.get_or_render(ds, path, m.image_size, m.image_channels // 3, progress=progress)


def _check_tdmpc2(config: ml_collections.ConfigDict) -> None:
  if not config.data.path:
    raise ValueError('config.data.source=tdmpc2 needs config.data.path (chunk file, glob '
                     'pattern or directory)')
  tdmpc2.tdmpc2_task_name(config.task)


@functools.lru_cache(maxsize=2)
def _load_tdmpc2_chunks(path: str, task: str) -> dataset_lib.Dataset:
  """Cached: training and the evaluation's goal splits read the same (large) files once."""
  name = tdmpc2.tdmpc2_task_name(task)
  try:
    return tdmpc2.load_tdmpc2(path, TDMPC2_TASK_SET, [name])
  except dataset_lib.DatasetError as err:
    raise dataset_lib.DatasetError(
        f'config.data.path={path!r} with config.task={task!r} (TD-MPC2 {name!r}): {err}') from err


def _load_tdmpc2(config: ml_collections.ConfigDict, progress: bool) -> dataset_lib.Dataset:
  del progress  # Reading chunk files shows no bar.
  return _load_tdmpc2_chunks(str(config.data.path), config.task)


SCRIPTED = envs.SUITE.name  # The suite's scripted episodes: the source of multi-task configs.
SOURCES.register(SCRIPTED, Source(_check_scripted, _load_scripted))
SOURCES.register('tdmpc2', Source(_check_tdmpc2, _load_tdmpc2))


def check_source(config: ml_collections.ConfigDict) -> None:
  """Raises a one-line ValueError if config.data's source or path cannot work (no file access)."""
  SOURCES.get(config.data.source).check(config)


def load_for_config(config: ml_collections.ConfigDict,
                    progress: bool = True) -> dataset_lib.Dataset:
  """The dataset `config` trains on, checked against config.obs_dim and config.action_dim.

  Returns:
    Dataset with observations [N, obs_dim] and actions [N, action_dim].

  Raises:
    ValueError: bad source or path, or a task TD-MPC2 does not have.
    DatasetError (a ValueError): files missing or unreadable, no episodes of the task in them, or
      sizes other than config.obs_dim / action_dim.
  """
  check_source(config)
  if tasks.is_multitask(config):  # Every task's dataset, task_ids per episode.
    return load_multitask(config, progress=progress)
  ds = SOURCES.get(config.data.source).load(config, progress)
  if ds.obs_dim != config.obs_dim or ds.act_dim != config.action_dim:
    raise dataset_lib.DatasetError(
        f'{config.data.source} data for {config.task} have observation/action sizes '
        f'({ds.obs_dim}, {ds.act_dim}), but config.obs_dim/action_dim are '
        f'({config.obs_dim}, {config.action_dim})')
  return ds


def load_multitask(config: ml_collections.ConfigDict, progress: bool = True) -> dataset_lib.Dataset:
  """All tasks' datasets, back to back; episode e of task k has task_ids[e] = k.

  Metadata: 'tasks' (the names, in index order) and 'per_task' (each task's own metadata).
  """
  parts = [load_for_config(tasks.task_config(config, k), progress=progress)
           for k in range(tasks.num_tasks(config))]
  return multitask.concatenate(parts, list(tasks.task_names(config)))
