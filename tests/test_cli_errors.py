"""experiments.train: unknown presets and an online batch the seed data cannot fill end in one
line and exit code 2, before any work starts (the checks themselves: test_config_checks.py)."""

import os
import re
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _train(tmp_path, *args):
  """The launcher's exit code and its stderr lines less absl/library log lines."""
  workdir = tmp_path / 'run'
  done = subprocess.run([sys.executable, '-m', 'experiments.train', f'--workdir={workdir}', *args],
                        cwd=tmp_path, capture_output=True, text=True, timeout=120,
                        env=dict(os.environ, PYTHONPATH=REPO))
  log = re.compile(r'^([IWEF]\d{4} |WARNING)')
  lines = [l for l in done.stderr.splitlines() if l.strip() and not log.match(l)]
  assert not workdir.exists()  # Nothing was started.
  return done.returncode, lines


@pytest.mark.parametrize('args,words', [
    (['--config=door_open.py:nosuch'], ['--config', "'nosuch'", "'smoke'"]),
    (['--config=door_open_online.py:nosuch'], ["'nosuch'", "'finetune'"]),
    (['--config=mt10.py:quick'], ["'quick'", 'mt10.py', "'smoke'"]),  # door_open's, not mt10's.
    (['--config=door_open.py:smoke', '--config.data.preset=bogus'],
     ['config.data.preset', "'bogus'", "'mixed'", "'weak'"]),
    (['--config=door_open_online.py:smoke', '--config.train.batch_size=16'],
     ['config.train.batch_size (16)', '12 windows', 'config.online.seed_steps=40']),
    (['--config=door_open.py:smoke', '--config.plan.nosuch=1'],
     ['--config.plan.nosuch', "'config.plan.nosuch'", 'no field']),
    (['--config=door_open.py:smoke', '--config.nosect.x=1'], ["'config.nosect'", 'no field']),
    (['--config=door_open.py:smoke', '--config.objective.hidden=8'],  # The section's old name.
     ['--config.objective.hidden', "'config.objective'", 'now config.critic']),
])
def test_bad_preset_or_batch_is_one_line_and_exit_code_2(tmp_path, args, words):
  code, lines = _train(tmp_path, *args)
  assert code == 2, lines[-30:]
  assert len(lines) == 1 and lines[0].startswith('error: '), lines[-30:]
  assert all(w in lines[0] for w in words), lines[0]


def test_a_workdir_of_another_config_is_one_line_and_exit_code_2(tmp_path):
  from ld_mpc_jax.configs import door_open
  from ld_mpc_jax.learn import checkpointing
  workdir = tmp_path / 'run'
  checkpointing.save_config(door_open.get_config('smoke'), str(workdir))
  done = subprocess.run([sys.executable, '-m', 'experiments.train', f'--workdir={workdir}',
                         '--config=door_open.py:smoke', '--config.seed=5'],
                        cwd=tmp_path, capture_output=True, text=True, timeout=120,
                        env=dict(os.environ, PYTHONPATH=REPO))
  lines = [l for l in done.stderr.splitlines() if l.startswith('error: ')]
  assert done.returncode == 2, done.stderr[-3000:]
  assert len(lines) == 1 and 'seed (0 -> 5)' in lines[0], done.stderr[-3000:]
  assert 'Traceback' not in done.stderr
  assert os.listdir(workdir) == [checkpointing.CONFIG_FILE]
