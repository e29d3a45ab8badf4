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
from typing import Callable, Tuple

import ml_collections

from ld_mpc_jax import envs
from ld_mpc_jax.data import collection
from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data import multitask, pixels
from ld_mpc_jax.data import tdmpc2
from ld_mpc_jax.ops.registry import Registry

TDMPC2_TASK_SET = 'mt80'  # The only TD-MPC2 task set with Meta-World tasks.


@dataclasses.dataclass(frozen=True)
class DataSpec:
  """What training data a config names, built once (`from_config`): `config.data`, the task (or
  the tasks of a multi-task config), the action repeat and the sizes it must have, and for a model
  of images the frames to render (`frames` stacked RGB frames of `image_size`; 0: states) and
  whether the robot's state follows them (`proprio`, `model.proprio`)."""
  source: str
  path: str
  preset: str
  episodes: int
  seed: int
  dir: str
  max_episode_steps: int
  task: str
  tasks: Tuple[str, ...]  # config.tasks of a multi-task config, else ().
  action_repeat: int
  obs_dim: int
  action_dim: int
  image_size: int
  frames: int
  proprio: bool = False

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'DataSpec':
    d, m = config.data, config.model
    images = m.encoder_type == 'conv' or m.dynamics_type == 'conv_frames'  # ModelSettings.images
    return cls(source=d.source, path=str(d.path), preset=d.preset, episodes=d.episodes,
               seed=d.seed, dir=d.dir, max_episode_steps=d.max_episode_steps, task=config.task,
               tasks=tuple(config.tasks) if 'tasks' in config and len(config.tasks) > 1 else (),
               action_repeat=config.eval.action_repeat, obs_dim=config.obs_dim,
               action_dim=config.action_dim, image_size=m.image_size,
               frames=m.image_channels // 3 if images else 0,
               proprio=bool(images and m.proprio))

  def check(self) -> None:
    """One-line ValueErrors for the source, its preset or path (no file access: its loader
    checks the files): the source's own check (`SOURCES`)."""
    SOURCES.get(self.source).check(self)

  def for_task(self, task: str) -> 'DataSpec':
    """The single-task spec of one task of a multi-task spec."""
    return dataclasses.replace(self, task=task, tasks=())


@dataclasses.dataclass(frozen=True)
class Source:
  """A kind of training data: `check(spec)` (no file access; one-line ValueError) and
  `load(spec, progress)` -> Dataset of spec.task."""
  check: Callable[[DataSpec], None]
  load: Callable[[DataSpec, bool], dataset_lib.Dataset]


SOURCES = Registry('data source', 'config.data.source')


def _check_scripted(spec: DataSpec) -> None:
  collection.check_preset(spec.preset, 'config.data.preset')


def _load_scripted(spec: DataSpec, progress: bool) -> dataset_lib.Dataset:
  """The collected episodes; for a model of images, those episodes rendered (data.pixels)."""
  ds = collection.get_or_collect(spec.task, spec.preset, spec.episodes, spec.seed, spec.dir,
                                 action_repeat=spec.action_repeat,
                                 max_episode_steps=spec.max_episode_steps, progress=progress)
  if not spec.frames:
    return ds
  path = collection.dataset_path(spec.dir, spec.task, spec.preset, spec.episodes, spec.seed,
                                 spec.action_repeat, spec.max_episode_steps)
  images = pixels.get_or_render(ds, path, spec.image_size, spec.frames, progress=progress)
  return pixels.with_proprio(images, ds) if spec.proprio else images


def _check_tdmpc2(spec: DataSpec) -> None:
  if not spec.path:
    raise ValueError('config.data.source=tdmpc2 needs config.data.path (chunk file, glob '
                     'pattern or directory)')
  tdmpc2.tdmpc2_task_name(spec.task)


@functools.lru_cache(maxsize=2)
def load_tdmpc2_chunks(path: str, task: str) -> dataset_lib.Dataset:
  """`task`'s episodes of TD-MPC2's chunk files at `path`; cached: training and the evaluation's
  goal splits read the same (large) files once."""
  name = tdmpc2.tdmpc2_task_name(task)
  try:
    return tdmpc2.load_tdmpc2(path, TDMPC2_TASK_SET, [name])
  except dataset_lib.DatasetError as err:
    raise dataset_lib.DatasetError(
        f'config.data.path={path!r} with config.task={task!r} (TD-MPC2 {name!r}): {err}') from err


def _load_tdmpc2(spec: DataSpec, progress: bool) -> dataset_lib.Dataset:
  del progress  # Reading chunk files shows no bar.
  return load_tdmpc2_chunks(spec.path, spec.task)


SCRIPTED = envs.SUITE.name  # The suite's scripted episodes: the source of multi-task configs.
SOURCES.register(SCRIPTED, Source(_check_scripted, _load_scripted))
SOURCES.register('tdmpc2', Source(_check_tdmpc2, _load_tdmpc2))




def load_dataset(spec: DataSpec, progress: bool = True) -> dataset_lib.Dataset:
  """The dataset of `spec`, checked against its obs_dim and action_dim.

  Returns:
    Dataset with observations [N, obs_dim] and actions [N, action_dim]; for a multi-task spec,
    every task's dataset back to back, task_ids per episode (`load_multitask`).

  Raises:
    ValueError: bad source or path, or a task TD-MPC2 does not have.
    DatasetError (a ValueError): files missing or unreadable, no episodes of the task in them, or
      sizes other than config.obs_dim / action_dim.
  """
  spec.check()
  if spec.tasks:
    return load_multitask(spec, progress=progress)
  ds = SOURCES.get(spec.source).load(spec, progress)
  if ds.obs_dim != spec.obs_dim or ds.act_dim != spec.action_dim:
    raise dataset_lib.DatasetError(
        f'{spec.source} data for {spec.task} have observation/action sizes '
        f'({ds.obs_dim}, {ds.act_dim}), but config.obs_dim/action_dim are '
        f'({spec.obs_dim}, {spec.action_dim})')
  return ds


def load_multitask(spec: DataSpec, progress: bool = True) -> dataset_lib.Dataset:
  """All tasks' datasets, back to back; episode e of task k has task_ids[e] = k.

  Metadata: 'tasks' (the names, in index order) and 'per_task' (each task's own metadata).
  """
  parts = [load_dataset(spec.for_task(task), progress=progress) for task in spec.tasks]
  return multitask.concatenate(parts, list(spec.tasks))
