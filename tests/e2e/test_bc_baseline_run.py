"""End to end: the BC baseline through its launcher evaluates on the planner's held-out episodes
and keeps every episode's outcome."""

import json
import os
import subprocess
import sys

import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import GoalSource

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.long
def test_bc_baseline_runs_the_planners_held_out_episodes(tmp_path):
  data_dir, out = str(tmp_path / 'data'), str(tmp_path / 'bc.json')
  cmd = [sys.executable, '-m', 'experiments.evaluate', 'bc', '--task=door-open-v3',
         '--preset=medium', '--episodes=2', '--steps=2', '--eval_episodes=3',
         f'--data_dir={data_dir}', f'--out={out}']
  done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
  assert done.returncode == 0, done.stderr[-2000:]
  with open(out) as f:
    report = json.load(f)
  # The planner's evaluation of a run on the same data (cached file) and evaluation seed.
  config = door_open.get_config('smoke')
  config.data.preset, config.data.episodes, config.data.seed = 'medium', 2, 0
  config.data.dir = data_dir
  planner_episodes = evaluation_suite.episodes(GoalSource.from_config(config), 'held_out', 0, 3)
  assert report['split'] == 'held_out'
  assert [(r['goal_id'], r['reset_seed']) for r in report['outcomes']] == [
      (e.goal_id, e.reset_seed) for e in planner_episodes]
  assert sum(r['success'] for r in report['outcomes']) / 3 == pytest.approx(
      report['success_rate'])
