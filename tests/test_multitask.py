"""Multi-task data (ld_mpc_jax.data.multitask) and the MT10 smoke run end to end."""

import os

import numpy as np
import pytest

from experiments.configs import mt10
from ld_mpc_jax import checkpointing, run_files, train
from ld_mpc_jax.config_checks import validate_config
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


def test_batch_size_must_split_over_the_tasks():
  c = mt10.get_config('smoke')
  c.train.batch_size = 12
  with pytest.raises(ValueError, match='multiple of the number of tasks'):
    validate_config(c)


@pytest.mark.long
def test_mt10_smoke_trains_checkpoints_resumes_and_evaluates_every_task(tmp_path):
  """The resumed run's update comes from the session's compilation cache (conftest.py)."""
  c = mt10.get_config('smoke')
  c.data.dir = str(tmp_path / 'data')
  workdir = str(tmp_path / 'run')
  first = mt10.get_config('smoke')
  first.data.dir, first.train.num_steps, first.eval.episodes = c.data.dir, 2, 0
  assert train.train_and_evaluate(first, workdir)['steps'] == 2  # Stops at a checkpoint.
  report = train.train_and_evaluate(c, workdir)  # Resumes from step 2, then evaluates.
  assert report['steps'] == 4
  steps = [int(r['step']) for r in run_files.read_csv(os.path.join(workdir, 'metrics.csv'))]
  assert steps == [2, 4]
  assert report['dataset']['episodes'] == 10  # One tiny episode per task.
  names = list(mt10.MT10_TASKS)
  table = report['per_task']['held_out']
  assert list(table) == ['plan', 'actor']
  for mode in table.values():
    assert list(mode['tasks']) == names
    rates = [s['success_rate'] for s in mode['tasks'].values()]
    assert mode['average']['success_rate'] == pytest.approx(np.mean(rates))
    assert mode['average']['episodes'] == 10
  rows = run_files.read_csv(os.path.join(workdir, 'episodes.csv'))
  assert len(rows) == 10 * 2 and [r['task'] for r in rows[::2]] == names
  md = open(os.path.join(workdir, 'report.md')).read()
  assert all(f'| {n} |' in md for n in names) and '**average**' in md
  assert os.path.getsize(os.path.join(workdir, 'tasks.png')) > 0
  config, params, step = checkpointing.load_for_evaluation(workdir)
  assert step == 4 and tuple(config.tasks) == mt10.MT10_TASKS
  assert params['task']['embedding'].shape == (10, c.model.task_dim)
