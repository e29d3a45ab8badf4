"""End to end: the main job trained from TD-MPC2 chunk files (config.data.source = 'tdmpc2'),
read by a stand-in torch module, or by torch itself with the [tdmpc2] extra."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ld_mpc_jax.eval import run_files
from ld_mpc_jax.data import tdmpc2
from tests.tdmpc2_chunks import (MT80_L, fake_torch, needs_extra,  # pylint: disable=unused-import
                                 write_chunk, write_mt80_chunk)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.long
def test_train_from_tdmpc2_chunks_end_to_end(fake_torch, tmp_path):
  from ld_mpc_jax.learn import checkpointing
  chunk = tmp_path / 'chunks'
  chunk.mkdir()
  obs = write_mt80_chunk(chunk / 'chunk_0.pt', ['mw-door-open', 'mw-reach', 'mw-door-open'])
  workdir = str(tmp_path / 'run')
  cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open.py:smoke',
         f'--workdir={workdir}', '--config.data.source=tdmpc2',
         f'--config.data.path={chunk}/chunk_*.pt', '--config.task=door-open-v3']
  env = dict(os.environ, PYTHONPATH=os.pathsep.join([fake_torch, REPO]))
  done = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  with open(os.path.join(workdir, 'report.json')) as f:
    report = json.load(f)
  assert report['steps'] == 4 and report['task'] == 'door-open-v3'
  assert report['dataset']['source'] == 'tdmpc2' and report['dataset']['episodes'] == 2
  assert report['dataset']['transitions'] == 2 * (MT80_L - 1)
  # Held-out goals only: TD-MPC2's goals were random per episode, there is no train split.
  assert list(report['evaluation']) == ['held_out']
  rows = run_files.read_csv(os.path.join(workdir, 'episodes.csv'))
  held = [r for r in rows if r['policy'] == 'plan']
  assert held and {r['split'] for r in rows} == {'held_out'}
  assert report['success_rate'] == sum(int(r['success']) for r in held) / len(held)
  # The normalisation in the checkpoint is that of the two door-open episodes of the chunk.
  config, params, step = checkpointing.load_for_evaluation(workdir)
  assert step == 4 and config.data.source == 'tdmpc2'
  np.testing.assert_allclose(params['encoder']['obs_mean'], obs[[0, 2]].reshape(-1, 39).mean(0),
                             rtol=1e-4, atol=1e-5)
  # A task the files do not hold: one line and exit code 2.
  cmd[-1] = '--config.task=drawer-open-v3'
  bad = subprocess.run(cmd + [f'--workdir={tmp_path / "bad"}'], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=300)
  assert bad.returncode == 2, bad.stderr[-2000:]
  assert bad.stderr.strip().splitlines()[-1].startswith('error: config.data.path=')
  assert 'No episodes' in bad.stderr


@needs_extra
def test_real_torch_chunk_trains(tmp_path):
  """The same run from a chunk written by torch.save (needs the [tdmpc2] extra)."""
  rng = np.random.default_rng(0)
  obs = rng.normal(size=(2, MT80_L, 39)).astype(np.float32)
  act = rng.uniform(-1, 1, (2, MT80_L, 4)).astype(np.float32)
  act[:, 0] = np.nan
  rew = rng.uniform(0, 10, (2, MT80_L)).astype(np.float32)
  rew[:, 0] = np.nan
  task = np.full((2, MT80_L), tdmpc2.task_index('mt80', 'mw-door-open'))
  write_chunk(tmp_path / 'chunk_0.pt', obs, act, rew, task)
  workdir = str(tmp_path / 'run')
  cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open.py:smoke',
         f'--workdir={workdir}', '--config.data.source=tdmpc2',
         f'--config.data.path={tmp_path}/chunk_*.pt', '--config.eval.episodes=0']
  done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  with open(os.path.join(workdir, 'report.json')) as f:
    report = json.load(f)
  assert report['steps'] == 4 and report['dataset']['episodes'] == 2
