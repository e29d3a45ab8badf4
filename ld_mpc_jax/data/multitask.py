"""Data of a multi-task config: every task's scripted dataset, and task-balanced batches.

Each task's dataset is the single-task one (`sources.load_dataset` of `DataSpec.for_task`:
the same presets, collected once and cached under the same file names). `concatenate` joins them
into one Dataset whose `task_ids` give each episode's task index (the position in config.tasks);
`TaskBalancedBuffer` draws the same number of windows from every task for each batch.
"""

from typing import Dict, List

import numpy as np

from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data import replay


def concatenate(parts: List[dataset_lib.Dataset], names: List[str]) -> dataset_lib.Dataset:
  """Datasets [task 0, task 1, ...] -> one Dataset with task_ids 0, 1, ... per episode."""
  offsets = np.cumsum([0] + [p.observations.shape[0] for p in parts[:-1]])
  keys = set.intersection(*(set(p.episode_data) for p in parts)) if parts else set()
  return dataset_lib.Dataset(
      observations=np.concatenate([p.observations for p in parts]),
      actions=np.concatenate([p.actions for p in parts]),
      rewards=np.concatenate([p.rewards for p in parts]),
      successes=np.concatenate([p.successes for p in parts]),
      episode_starts=np.concatenate([p.episode_starts + o for p, o in zip(parts, offsets)]),
      episode_lengths=np.concatenate([p.episode_lengths for p in parts]),
      task_ids=np.concatenate([np.full(p.num_episodes, k, np.int32)
                               for k, p in enumerate(parts)]),
      episode_data={k: np.concatenate([p.episode_data[k] for p in parts]) for k in sorted(keys)},
      metadata=dict(tasks=names, per_task=[p.metadata for p in parts])).validate()


def task_subset(ds: dataset_lib.Dataset, task: int) -> dataset_lib.Dataset:
  """The episodes of one task index, as a Dataset of their own."""
  episodes = [ds.episode(e) for e in np.flatnonzero(ds.task_ids == task)]
  if not episodes:
    raise dataset_lib.DatasetError(f'the dataset has no episode of task index {task}')
  return dataset_lib.Dataset.from_episodes(episodes, task_ids=[task] * len(episodes))


class TaskBalancedBuffer:
  """Windows of every task in equal numbers: one ReplayBuffer per task.

  `sample(B)` draws B / num_tasks windows from each task's buffer and returns them task-major
  (rows g*b .. g*b + b - 1 of task g) with `task` int32 [B], as `tasks.multitask_loss` needs.
  """

  def __init__(self, dataset: dataset_lib.Dataset, seq_len: int, num_tasks: int,
               seed: int = 0):
    self.num_tasks = int(num_tasks)
    self.buffers = [replay.ReplayBuffer(task_subset(dataset, k), seq_len, seed=[seed, k])
                    for k in range(self.num_tasks)]
    self.num_windows = sum(b.num_windows for b in self.buffers)

  def sample(self, batch_size: int) -> Dict[str, np.ndarray]:
    """dict(obs [B, T, obs_dim], action [B, T-1, A], reward [B, T-1], task int32 [B])."""
    if batch_size % self.num_tasks:
      raise ValueError(f'batch_size ({batch_size}) must be a multiple of the number of tasks '
                       f'({self.num_tasks})')
    share = batch_size // self.num_tasks
    parts = [b.sample(share) for b in self.buffers]
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    out['task'] = np.repeat(np.arange(self.num_tasks, dtype=np.int32), share)
    return out

  def skip(self, batches: int, batch_size: int) -> None:
    """Advances every task's sampler as `batches` calls of `sample(batch_size)` would."""
    for buffer in self.buffers:
      buffer.skip(batches, batch_size // self.num_tasks)


def make_buffer(dataset: dataset_lib.Dataset, seq_len: int, num_tasks: int = 1, seed: int = 0):
  """The training sampler: task-balanced over `num_tasks` tasks (a multi-task config), else
  uniform."""
  if num_tasks > 1:
    return TaskBalancedBuffer(dataset, seq_len, num_tasks, seed=seed)
  return replay.ReplayBuffer(dataset, seq_len, seed=seed)
