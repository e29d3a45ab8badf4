"""experiments.evaluate --video: the video and evaluation.json each go to their own file."""

import json
import os
import subprocess
import sys

import jax

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.runs import loop as runs
from ld_mpc_jax.learn.train_state import LearnSettings, create_train_state

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MARKER = b'not json: a stand-in for the mp4'
# The launcher with run_evaluation's video path replaced by a marker file (no rendering, so no
# OpenGL); every other evaluation is the real one.
_SCRIPT = f"""
from absl import app
from ld_mpc_jax.runs import loop as runs
real = runs.run_evaluation
def fake(spec, params, mode, num_episodes, seed, video_path=None, **kwargs):
  if video_path is None:
    return real(spec, params, mode, num_episodes, seed, **kwargs)
  with open(video_path, 'wb') as f:
    f.write({MARKER!r})
  return dict(video_path=video_path)
runs.run_evaluation = fake
from ld_mpc_jax.cli import evaluate
app.run(evaluate.main)
"""


def test_video_and_json_are_separate_files(tmp_path, smoke_config):
  workdir = str(tmp_path / 'run')
  checkpointing.save_config(smoke_config, workdir)
  state = create_train_state(LearnSettings.from_config(smoke_config), jax.random.key(0))
  runs.save_checkpoint(workdir, checkpointing.checkpoint_manager(workdir), state, 1, 0.0)
  done = subprocess.run(
      [sys.executable, '-c', _SCRIPT, f'--workdir={workdir}', '--video', '--modes=actor',
       '--splits=held_out', '--episodes=1'],
      cwd=REPO, capture_output=True, text=True, timeout=300,
      env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 0, done.stderr[-3000:]
  video = os.path.join(workdir, 'planner.mp4')
  with open(video, 'rb') as f:
    assert f.read() == MARKER  # Not overwritten by the JSON.
  with open(os.path.join(workdir, 'evaluation.json')) as f:
    out = json.load(f)
  assert out['video'] == video and 'video_error' not in out
  assert out['records'] and out['step'] == 0  # The state's own step
  # The evaluated cell is kept for a re-run (--nocache: none), with the same records.
  (cell,) = os.listdir(os.path.join(workdir, 'evals'))
  assert cell.startswith('actor_held_out_seed0_')
  with open(os.path.join(workdir, 'evals', cell)) as f:
    kept = json.load(f)['records']
  assert [r['return'] for r in kept] == [r['return'] for r in out['records']]


def test_an_existing_video_is_kept_unless_overwrite(tmp_path):
  workdir = tmp_path / 'run'
  workdir.mkdir()
  (workdir / 'planner.mp4').write_bytes(MARKER)
  done = subprocess.run(
      [sys.executable, '-m', 'experiments.evaluate', f'--workdir={workdir}', '--video'],
      cwd=REPO, capture_output=True, text=True, timeout=300,
      env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 2, done.stderr[-3000:]
  assert done.stderr.strip().splitlines()[-1] == (
      f'error: {workdir}/planner.mp4 exists (an earlier result); choose another --video_out or '
      'pass --overwrite')
  assert (workdir / 'planner.mp4').read_bytes() == MARKER
  assert os.listdir(workdir) == ['planner.mp4']
