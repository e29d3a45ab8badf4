"""End to end: the MT10 smoke run trains, checkpoints, resumes and evaluates every task."""

import os

import numpy as np
import pytest

from ld_mpc_jax.configs import mt10
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.eval import run_files
from ld_mpc_jax.runs import train


@pytest.mark.long
def test_mt10_smoke_trains_checkpoints_resumes_and_evaluates_every_task(tmp_path):
  """The resumed run's update comes from the session's compilation cache (conftest.py)."""
  c = mt10.get_config('smoke')
  c.data.dir = str(tmp_path / 'data')
  workdir = str(tmp_path / 'run')
  first = mt10.get_config('smoke')
  first.data.dir, first.train.num_steps, first.eval.episodes = c.data.dir, 2, 0
  assert train.train_and_evaluate(first, workdir)['steps'] == 2  # Stops at a checkpoint.
  # Resumes from step 2 with more steps and an evaluation, then evaluates.
  report = train.train_and_evaluate(c, workdir, continue_with_changes=True)
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
