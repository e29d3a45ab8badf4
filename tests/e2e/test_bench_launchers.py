"""End to end: experiments.benchmark_training writes its JSON and table; compare_update_speed
times this checkout against itself."""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.long
def test_benchmark_training_writes_json(tmp_path):
  out = str(tmp_path / 'bench.json')
  cmd = [sys.executable, '-m', 'experiments.benchmark_training', '--configs=door_open.py:smoke',
         '--repeats=2', '--warmup=1', f'--out={out}', '--peak_size=256', '--peak_repeats=2',
         '--config.critic.latent_rollout=False']  # Less to compile; value targets still scan.
  done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  with open(out) as f:
    entries = json.load(f)
  assert isinstance(entries, list) and len(entries) == 1
  e = entries[0]
  for key in ('name', 'step_ms', 'gflop', 'peak_gflops', 'bound_ratio', 'devices'):
    assert key in e, key
  assert e['name'] == 'door_open.py:smoke' and e['devices'] == 1 and e['batch_size'] == 8
  assert set(e['step_ms']) == {'median', 'min', 'max', 'n'} and e['step_ms']['n'] == 2
  assert 0 < e['step_ms']['min'] <= e['step_ms']['median'] <= e['step_ms']['max']
  assert e['gflop'] > 0 and e['peak_gflops'] > 0
  # The update's scans (the value targets') add iterations the compiled count misses.
  assert e['gflop'] > e['gflop_xla_once'] > 0
  bound_ms = e['gflop'] / e['peak_gflops'] * 1e3
  np.testing.assert_allclose(e['bound_ratio'], e['step_ms']['median'] / bound_ms, rtol=1e-9)
  assert os.path.getsize(os.path.splitext(out)[0] + '.md') > 0


@pytest.mark.long
def test_compare_update_speed_runs_both_checkouts():
  """This checkout against itself at smoke size: both versions time, ratio printed."""
  repo = REPO
  done = subprocess.run(
      [sys.executable, '-m', 'experiments.benchmark_training', 'versions', f'--baseline={repo}',
       '--config=door_open.py:smoke', '--steps=2'],
      cwd=repo, env=dict(os.environ, PYTHONPATH=repo), capture_output=True, text=True,
      timeout=600)
  assert done.returncode == 0, done.stderr[-2000:]
  match = re.search(r'this checkout ([\d.]+) ms, baseline ([\d.]+) ms .* ratio this/baseline '
                    r'([\d.]+)', done.stdout)
  assert match and all(float(x) > 0 for x in match.groups())
  # The same code from the same state, batch and key: the same first step.
  diff = re.search(r'max relative difference of the (\d+) shared metrics ([\d.e+-]+)',
                   done.stdout)
  assert diff and int(diff.group(1)) > 5 and float(diff.group(2)) < 1e-6
  bad = subprocess.run([sys.executable, '-m', 'experiments.benchmark_training', 'versions',
                        '--baseline=/nonexistent'], cwd=repo, capture_output=True, text=True,
                       env=dict(os.environ, PYTHONPATH=repo), timeout=120)
  assert bad.returncode == 2 and 'has no ld_mpc_jax package' in bad.stderr
