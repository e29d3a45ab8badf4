"""End to end: an offline smoke run killed with SIGKILL resumes from its last checkpoint and
reaches the same final step (through the launcher, in subprocesses)."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from ld_mpc_jax.eval import run_files

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope='module')
def data_dir(tmp_path_factory):
  return str(tmp_path_factory.mktemp('data'))


# Long (74 s of the default run's budget on a quiet 2-core machine): the default run checks a
# crash and its resume in-process (tests/test_train.py).
@pytest.mark.long
def test_kill_and_resume_reaches_the_same_step(tmp_path, data_dir):
  workdir = str(tmp_path / 'run')
  cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open.py:smoke',
         f'--workdir={workdir}', f'--config.data.dir={data_dir}',
         '--config.train.num_steps=15', '--config.train.checkpoint_every=5',
         '--config.train.log_every=5', '--config.train.eval_every=1000',
         '--config.eval.episodes=0']  # Resuming is tested here; evaluation elsewhere.
  proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
  ckpt_dir = os.path.join(workdir, 'checkpoints')
  deadline = time.time() + 240
  while time.time() < deadline and proc.poll() is None:
    if os.path.isdir(ckpt_dir) and any(d.isdigit() for d in os.listdir(ckpt_dir)):
      break
    time.sleep(0.05)
  assert proc.poll() is None, 'the run ended before it could be killed'
  if not (os.path.isdir(ckpt_dir) and any(d.isdigit() for d in os.listdir(ckpt_dir))):
    proc.kill()
    proc.wait()
    pytest.fail('no checkpoint within 240 s: the machine is too loaded for this check')
  os.kill(proc.pid, signal.SIGKILL)
  proc.wait()
  killed_at = max(int(d) for d in os.listdir(ckpt_dir) if d.isdigit())
  assert killed_at < 15
  assert not os.path.exists(os.path.join(workdir, 'report.json'))
  done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
  assert done.returncode == 0, done.stderr[-2000:]
  with open(os.path.join(workdir, 'report.json')) as f:
    assert json.load(f)['steps'] == 15
  steps = [int(r['step']) for r in run_files.read_csv(os.path.join(workdir, 'metrics.csv'))]
  assert steps[-1] == 15 and min(steps) <= killed_at
