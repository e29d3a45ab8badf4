"""The tasks of a config: `config.task`, or the names of a multi-task config (`config.tasks`).

The task-conditioned networks that use them are ld_mpc_jax.model.tasks.
"""

from typing import Tuple

import ml_collections

from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.envs import metaworld_env


def task_names(config: ml_collections.ConfigDict) -> Tuple[str, ...]:
  """The tasks of a multi-task config (config.tasks), else (config.task,)."""
  names = tuple(config.tasks) if 'tasks' in config else ()
  return names if names else (config.task,)


def num_tasks(config: ml_collections.ConfigDict) -> int:
  return len(task_names(config))


def is_multitask(config: ml_collections.ConfigDict) -> bool:
  """Whether the agent is task-conditioned (two or more tasks)."""
  return num_tasks(config) > 1


def check_tasks(config: ml_collections.ConfigDict) -> None:
  """Raises a one-line ValueError for unknown or repeated task names."""
  names = task_names(config)
  if len(set(names)) != len(names):
    raise ValueError(f'config.tasks repeats a task: {list(names)}')
  for name in names:
    metaworld_env.check_task(name)


def task_config(config: ml_collections.ConfigDict, task: int) -> ml_collections.ConfigDict:
  """A copy of `config` for task index `task` alone (config.task set, config.tasks removed).

  With `bind(params, task)` it is a single-task agent: data, goal splits and evaluation of that
  task use it unchanged.
  """
  name = task_names(config)[task]
  out = with_overrides(config, {'task': name})
  if 'tasks' in out:
    del out['tasks']
  return out
