"""Multi-task data (ld_mpc_jax.data.multitask): episodes labelled with their task, task-balanced
batches. (The MT10 smoke run end to end: tests/e2e/test_mt10_run.py.)"""

import numpy as np
import pytest

from ld_mpc_jax.data import multitask
from ld_mpc_jax.data.dataset import Dataset


def _task_dataset(task: int, lengths) -> Dataset:
  """Episodes whose observations all hold the value `task`, rewards the episode's index."""
  eps = [dict(obs=np.full((n + 1, 39), task, np.float32), action=np.zeros((n, 4), np.float32),
              reward=np.full(n, e, np.float32)) for e, n in enumerate(lengths)]
  return Dataset.from_episodes(eps)


def test_concatenate_labels_each_episode_with_its_task():
  parts = [_task_dataset(0, [5, 9]), _task_dataset(1, [7]), _task_dataset(2, [3, 3, 12])]
  ds = multitask.concatenate(parts, ['a', 'b', 'c'])
  np.testing.assert_array_equal(ds.task_ids, [0, 0, 1, 2, 2, 2])
  for e in range(ds.num_episodes):
    assert np.all(ds.episode(e)['obs'] == ds.task_ids[e])
  assert ds.metadata['tasks'] == ['a', 'b', 'c']
  sub = multitask.task_subset(ds, 2)
  np.testing.assert_array_equal(sub.episode_lengths, [3, 3, 12])


def test_batches_hold_equal_shares_of_every_task():
  # Task 0 has 30x the windows of task 1: a uniform sampler would hardly ever draw task 1.
  parts = [_task_dataset(0, [300]), _task_dataset(1, [12]), _task_dataset(2, [40, 40])]
  ds = multitask.concatenate(parts, ['a', 'b', 'c'])
  buffer = multitask.TaskBalancedBuffer(ds, seq_len=4, num_tasks=3, seed=0)
  for _ in range(5):
    batch = buffer.sample(12)
    np.testing.assert_array_equal(batch['task'], np.repeat([0, 1, 2], 4))
    # Task-major rows, each window from its own task's episodes.
    np.testing.assert_array_equal(batch['obs'][:, :, 0], np.repeat([0, 1, 2], 4)[:, None]
                                  * np.ones((1, 4)))
    assert batch['obs'].shape == (12, 4, 39) and batch['reward'].shape == (12, 3)
  counts = np.bincount(np.concatenate([buffer.sample(30)['task'] for _ in range(4)]))
  np.testing.assert_array_equal(counts, [40, 40, 40])
  with pytest.raises(ValueError, match='multiple of the number of tasks'):
    buffer.sample(10)


def test_skip_advances_every_task_as_sampling_would():
  """A resumed run's sampler, past the batches before its checkpoint, draws what the
  uninterrupted run's draws next."""
  def stepped(task, n):  # Observations: the task and the step.
    obs = np.stack([np.full(n + 1, task), np.arange(n + 1)], -1).repeat([1, 38], axis=1)
    return Dataset.from_episodes([dict(obs=obs.astype(np.float32),
                                       action=np.zeros((n, 4), np.float32),
                                       reward=np.zeros(n, np.float32))])
  ds = multitask.concatenate([stepped(0, 50), stepped(1, 20)], ['a', 'b'])
  whole = multitask.TaskBalancedBuffer(ds, seq_len=4, num_tasks=2, seed=3)
  for _ in range(6):
    whole.sample(8)
  resumed = multitask.TaskBalancedBuffer(ds, seq_len=4, num_tasks=2, seed=3)
  resumed.skip(6, 8)
  for _ in range(2):
    np.testing.assert_array_equal(resumed.sample(8)['obs'], whole.sample(8)['obs'])
