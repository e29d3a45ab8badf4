"""ld_mpc_jax.eval.run_files: CSV logs and episodes.csv written and read back, the plots their CSVs
call for, provenance."""

import csv
import os
import re
import subprocess

import pytest

from ld_mpc_jax.eval import run_files

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EPISODE_FIELDS = ['policy', 'split', 'eval_seed', 'episode', 'reset_seed', 'goal_id', 'success',
                  'first_success', 'return', 'length', 'env_steps']


def test_append_csv_writes_the_header_once(tmp_path):
  path = str(tmp_path / 'metrics.csv')
  assert run_files.read_csv(path) == []  # No file yet.
  run_files.append_csv(path, dict(step=1, loss=0.5))
  run_files.append_csv(path, dict(step=2, loss=0.25))
  with open(path) as f:
    assert f.read().splitlines() == ['step,loss', '1,0.5', '2,0.25']
  assert run_files.read_csv(path) == [dict(step='1', loss='0.5'), dict(step='2', loss='0.25')]


def test_drop_rows_after_keeps_the_rows_up_to_the_step(tmp_path):
  path = str(tmp_path / 'online.csv')
  for step in (40, 80, 120, 160):
    run_files.append_csv(path, dict(env_steps=step, ret=step / 10))
  run_files.drop_rows_after(path, 'env_steps', 80)
  with open(path) as f:
    assert f.read().splitlines() == ['env_steps,ret', '40,4.0', '80,8.0']
  run_files.drop_rows_after(path, 'env_steps', 80)  # Nothing past it: unchanged.
  assert [r['env_steps'] for r in run_files.read_csv(path)] == ['40', '80']
  run_files.drop_rows_after(str(tmp_path / 'absent.csv'), 'env_steps', 80)  # No file: nothing.
  assert not os.path.exists(tmp_path / 'absent.csv')


def _record(episode, success, **extra):
  return dict(run=3, policy='plan', split='held_out', eval_seed=0, episode=episode,
              reset_seed=100 + episode, goal_id=f'g{episode}', success=success,
              first_success=5 if success else None, env_steps=40, length=20,
              **{'return': 1.5 * episode}, **extra)


def test_episodes_csv_holds_one_row_per_record_and_nothing_else(tmp_path):
  path = str(tmp_path / 'episodes.csv')
  records = [_record(0, 1, decisions_per_s=9.0, departures=2), _record(1, 0)]
  run_files.write_records(path, records)
  with open(path) as f:
    rows = list(csv.reader(f))
  assert rows[0] == ['run'] + EPISODE_FIELDS  # Extra fields (speed, departures) left out.
  assert rows[1:] == [['3', 'plan', 'held_out', '0', '0', '100', 'g0', '1', '5', '0.0', '20',
                       '40'],
                      ['3', 'plan', 'held_out', '0', '1', '101', 'g1', '0', '', '1.5', '20',
                       '40']]
  # Replaced whole, not appended to, and no temporary file left behind.
  run_files.write_records(path, [_record(2, 1)])
  assert [r['episode'] for r in run_files.read_csv(path)] == ['2']
  assert os.listdir(tmp_path) == ['episodes.csv']


def test_multitask_records_gain_a_task_column(tmp_path):
  path = str(tmp_path / 'episodes.csv')
  run_files.write_records(path, [_record(0, 1, task='reach-v3'), _record(1, 1, task='push-v3')])
  rows = run_files.read_csv(path)
  assert list(rows[0]) == ['run', 'task'] + EPISODE_FIELDS
  assert [r['task'] for r in rows] == ['reach-v3', 'push-v3']


def test_plots_are_drawn_for_the_csvs_that_exist(tmp_path):
  workdir = str(tmp_path)
  run_files.write_plots(workdir)  # No CSV: no plot, no error.
  assert os.listdir(workdir) == []
  for step, loss in ((2, 1.0), (4, 0.5)):
    run_files.append_csv(os.path.join(workdir, 'metrics.csv'),
                         dict(step=step, loss=loss, loss_dyn=loss / 2, grad_norm=3.0))
    run_files.append_csv(os.path.join(workdir, 'eval.csv'),
                         dict(step=step, success_rate=0.5, ci_lo=0.2, ci_hi=0.8,
                              mean_return=10.0))
  run_files.write_plots(workdir)
  assert sorted(os.listdir(workdir)) == ['eval.csv', 'losses.png', 'metrics.csv', 'success.png']
  run_files.append_csv(os.path.join(workdir, run_files.ONLINE_CSV),
                       dict(env_steps=40, episode_success=0.0, episode_return=3.0))
  run_files.append_csv(os.path.join(workdir, run_files.LOSSES_CSV), dict(env_steps=40, loss=2.0))
  run_files.write_plots(workdir)
  assert os.path.getsize(os.path.join(workdir, 'online.png')) > 0


def test_provenance_names_the_checkout_and_package_versions():
  from importlib import metadata
  head = subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=REPO, capture_output=True, text=True)
  if head.returncode:
    pytest.skip('not a git checkout')
  commit = run_files.git_commit()
  assert re.fullmatch('[0-9a-f]{40}', commit) and commit == head.stdout.strip()
  v = run_files.versions()
  assert {'jax', 'flax', 'metaworld', 'mujoco', 'numpy', 'device'} <= set(v)
  assert v['numpy'] == metadata.version('numpy') and v['jax'] == metadata.version('jax')
  assert run_files.primary()  # A single process is process 0.


def test_each_start_of_a_run_writes_its_provenance_and_records_copy_it(tmp_path):
  """Issue 102: a run's commit, dirty flag and command line are written by the run at each
  start, and `report records` copies them beside the records (no provenance by hand)."""
  import json
  import subprocess
  from ld_mpc_jax.cli import records
  from ld_mpc_jax.eval import run_files
  root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  head = subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=root, capture_output=True,
                        text=True).stdout.strip()
  argv = [os.path.join(root, 'experiments', 'train.py'), '--config=door_open.py:smoke',
          '--workdir=my run']
  for _ in range(2):  # A start and a resume.
    run_files.write_provenance(str(tmp_path), argv)
  lines = [json.loads(l) for l in (tmp_path / run_files.PROVENANCE).read_text().splitlines()]
  assert len(lines) == 2
  assert lines[0]['commit'] == (head or None) and isinstance(lines[0]['dirty'], bool)
  assert lines[0]['command'] == ("python -m experiments.train --config=door_open.py:smoke "
                                 "'--workdir=my run'")
  (tmp_path / 'episodes.csv').write_text('run,policy,success\n0,plan,1\n')
  written = records.write_records(str(tmp_path), str(tmp_path / 'out'))
  assert str(tmp_path / 'out' / run_files.PROVENANCE) in written
  copied = [json.loads(l) for l in (tmp_path / 'out' / run_files.PROVENANCE).read_text().splitlines()]
  assert copied == [dict(l, cwd='<checkout>') for l in lines]  # No machine path in the records.
