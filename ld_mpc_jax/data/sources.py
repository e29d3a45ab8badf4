"""The training data a config names: scripted Meta-World collection or TD-MPC2's chunk files.

`config.data.source` picks the source:
* 'metaworld' (default): episodes of the scripted policies on `config.task`, collected once and
  cached under `config.data.dir` (`collection.get_or_collect`);
* 'tdmpc2': the `config.task` episodes of TD-MPC2's mt80 chunk files at `config.data.path` (a file,
  a glob pattern or a directory). TD-MPC2 recorded Meta-World v2; its 'mw-door-open' is this
  project's 'door-open-v3' (`tdmpc2.from_metaworld_v3`).
A multi-task config (`config.tasks`) gets every task's scripted dataset joined, with each
episode's task index (`load_multitask`).
"""

import functools

import ml_collections

from ld_mpc_jax import tasks
from ld_mpc_jax.data import collection
from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data import multitask
from ld_mpc_jax.data import tdmpc2

SOURCES = ('metaworld', 'tdmpc2')
TDMPC2_TASK_SET = 'mt80'  # The only TD-MPC2 task set with Meta-World tasks.


def source(config: ml_collections.ConfigDict) -> str:
  """config.data.source; 'metaworld' for configs saved before the field existed."""
  return config.data.get('source', 'metaworld')


def max_episode_steps(config: ml_collections.ConfigDict) -> int:
  """Environment steps per collected episode: config.data.max_episode_steps, else Meta-World's."""
  return config.data.get('max_episode_steps') or collection.metaworld_env.METAWORLD_MAX_PATH_LENGTH


def check_source(config: ml_collections.ConfigDict) -> None:
  """Raises a one-line ValueError if config.data's source or path cannot work (no file access)."""
  src = source(config)
  if src not in SOURCES:
    raise ValueError(f"config.data.source must be one of {', '.join(SOURCES)}, got {src!r}")
  if src == 'tdmpc2':
    if not config.data.get('path'):
      raise ValueError('config.data.source=tdmpc2 needs config.data.path (chunk file, glob '
                       'pattern or directory)')
    tdmpc2.from_metaworld_v3(config.task)
  else:  # Scripted data, collected at this preset (one task or each of config.tasks).
    collection.check_preset(config.data.preset, 'config.data.preset')


@functools.lru_cache(maxsize=2)
def _load_tdmpc2(path: str, task: str) -> dataset_lib.Dataset:
  """Cached: training and the evaluation's goal splits read the same (large) files once."""
  name = tdmpc2.from_metaworld_v3(task)
  try:
    return tdmpc2.load_tdmpc2(path, TDMPC2_TASK_SET, [name])
  except dataset_lib.DatasetError as err:
    raise dataset_lib.DatasetError(
        f'config.data.path={path!r} with config.task={task!r} (TD-MPC2 {name!r}): {err}') from err


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
  d = config.data
  if source(config) == 'metaworld':
    ds = collection.get_or_collect(config.task, d.preset, d.episodes, d.seed, d.dir,
                                   action_repeat=config.eval.action_repeat,
                                   max_episode_steps=max_episode_steps(config), progress=progress)
  else:
    ds = _load_tdmpc2(str(d.path), config.task)
  if ds.obs_dim != config.obs_dim or ds.act_dim != config.action_dim:
    raise dataset_lib.DatasetError(
        f'{source(config)} data for {config.task} have observation/action sizes '
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
