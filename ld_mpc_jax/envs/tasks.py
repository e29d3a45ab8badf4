"""The tasks of a config, built once (`Tasks.from_config`): `config.task`, or the names of a
multi-task config (`config.tasks`).

The task-conditioned networks that use them are ld_mpc_jax.model.tasks. A task's own settings are
the multi-task ones narrowed to it (`DataSpec.for_task`, `EvalSpec.tasks`), not a copy of the
config.
"""

import dataclasses
from typing import Tuple

import ml_collections

from ld_mpc_jax.envs import metaworld_env


@dataclasses.dataclass(frozen=True)
class Tasks:
  """The task names of a config, in task-index order: `config.tasks` of a multi-task config,
  else (`config.task`,). Frozen and hashable."""
  names: Tuple[str, ...]

  @classmethod
  def from_config(cls, config: ml_collections.ConfigDict) -> 'Tasks':
    names = tuple(config.tasks) if 'tasks' in config else ()
    return cls(names if names else (config.task,))

  def __len__(self) -> int:
    return len(self.names)

  @property
  def multitask(self) -> bool:
    """Whether the agent is task-conditioned (two or more tasks)."""
    return len(self.names) > 1

  def check(self) -> None:
    """Raises a one-line ValueError for unknown or repeated task names."""
    if len(set(self.names)) != len(self.names):
      raise ValueError(f'config.tasks repeats a task: {list(self.names)}')
    for name in self.names:
      metaworld_env.check_task(name)
