"""End to end: the online smoke job through the launcher (acting, buffer, updates, checkpoints),
and a SIGKILL with resume that ends where the uninterrupted run ends.

The runs go through the launcher in subprocesses that share the session's compilation cache.
"""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax import data
from ld_mpc_jax.data import online_buffer
from ld_mpc_jax.eval import run_files

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ENV_STEPS = 200  # Five waves of 2 episodes x 20 environment steps; the first one random.


@pytest.fixture(scope='module')
def launch():
  """launch(workdir) -> Popen of the smoke online job (no evaluation).

  The subprocesses inherit the session's compilation cache (conftest.py), so the update and the
  planner compile once for all of them.
  """
  def start(workdir, *extra):
    cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open_online.py:smoke',
           f'--workdir={workdir}', f'--config.online.env_steps={ENV_STEPS}',
           '--config.eval.episodes=0', *extra]
    return subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
  return start


@pytest.fixture(scope='module')
def finished(launch, tmp_path_factory):
  """Workdir of one uninterrupted smoke run."""
  workdir = str(tmp_path_factory.mktemp('online') / 'run')
  proc = launch(workdir)
  _, err = proc.communicate(timeout=600)
  assert proc.returncode == 0, err[-2000:]
  return workdir


def _buffer(workdir, step):
  return data.load(online_buffer.buffer_path(workdir, step))


@pytest.mark.long  # Its fixture runs the smoke job.
def test_smoke_run_acts_fills_the_buffer_updates_and_checkpoints(finished):
  waves = run_files.read_csv(os.path.join(finished, run_files.ONLINE_CSV))
  assert [int(w['env_steps']) for w in waves] == [40, 80, 120, 160, 200]
  assert [w['acting'] for w in waves] == ['random'] + ['planner'] * 4
  # update_ratio 0.1: floor(0.1 x environment steps) updates, none before the seed wave is in.
  assert [int(w['updates']) for w in waves] == [0, 8, 12, 16, 20]
  ds = _buffer(finished, ENV_STEPS)
  assert ds.num_episodes == 10 and list(ds.episode_lengths) == [10] * 10  # 10 decisions each.
  assert ds.metadata['online'] == dict(env_steps=200, updates=20, episodes=10, normalized=True,
                                       pretrain_updates=0,
                                       train_seconds=ds.metadata['online']['train_seconds'])
  assert np.all(np.abs(ds.actions) <= 1.0) and np.all(np.isfinite(ds.observations))
  manager = checkpointing.checkpoint_manager(finished)
  assert manager.all_steps() == [120, 160, 200]  # train.max_checkpoints = 3, at environment steps.
  assert sorted(os.listdir(os.path.join(finished, online_buffer.BUFFER_DIR))) == [
      'buffer_120.npz', 'buffer_160.npz', 'buffer_200.npz']  # Each beside its orbax step.
  config, _, step = checkpointing.load_for_evaluation(finished)
  assert step == 20 and config.online.enabled  # TrainState.step counts updates.
  losses = run_files.read_csv(os.path.join(finished, run_files.LOSSES_CSV))
  assert [int(r['env_steps']) for r in losses] == [80, 120, 160, 200]
  assert all(np.isfinite(float(r['loss'])) for r in losses)
  with open(os.path.join(finished, 'report.json')) as f:
    report = json.load(f)
  assert (report['env_steps'], report['updates'], report['mode']) == (200, 20, 'from scratch')
  assert os.path.getsize(os.path.join(finished, 'online.png')) > 0


@pytest.mark.long
def test_sigkill_and_resume_restore_buffer_and_step_counter_exactly(finished, launch, tmp_path):
  workdir = str(tmp_path / 'run')
  proc = launch(workdir)
  ckpt_dir = os.path.join(workdir, 'checkpoints')
  deadline = time.time() + 300
  while time.time() < deadline and proc.poll() is None:  # Kill once a checkpoint with updates
    if os.path.isdir(ckpt_dir) and '80' in os.listdir(ckpt_dir):  # is complete.
      break
    time.sleep(0.02)
  assert proc.poll() is None, 'the run ended before it could be killed'
  os.kill(proc.pid, signal.SIGKILL)
  proc.wait()
  manager = checkpointing.checkpoint_manager(workdir)
  killed_at = manager.latest_step()
  assert 80 <= killed_at < ENV_STEPS
  saved = _buffer(workdir, killed_at)
  assert saved.metadata['online']['env_steps'] == killed_at
  resumed = launch(workdir)
  _, err = resumed.communicate(timeout=600)
  assert resumed.returncode == 0, err[-2000:]
  # The resumed run kept the saved episodes, and ended where the uninterrupted run ended.
  got, want = _buffer(workdir, ENV_STEPS), _buffer(finished, ENV_STEPS)
  n = saved.observations.shape[0]
  np.testing.assert_array_equal(got.observations[:n], saved.observations)
  for name in ('observations', 'actions', 'rewards', 'episode_lengths'):
    np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
  for name in ('env_steps', 'updates', 'episodes'):
    assert got.metadata['online'][name] == want.metadata['online'][name], name
  assert got.metadata['sampler_rng'] == want.metadata['sampler_rng']
  waves = run_files.read_csv(os.path.join(workdir, run_files.ONLINE_CSV))
  assert int(waves[-1]['env_steps']) == ENV_STEPS
  steps = [int(w['env_steps']) for w in waves]  # Rows logged after the checkpoint came once.
  assert steps == sorted(set(steps)), steps


@pytest.mark.long
def test_sigkill_of_a_two_seed_run_resumes_both_seeds_where_the_whole_run_ends(launch, tmp_path):
  seeds = '--config.train.num_seeds=2'
  whole = str(tmp_path / 'whole')
  proc = launch(whole, seeds)
  _, err = proc.communicate(timeout=900)
  assert proc.returncode == 0, err[-2000:]
  workdir = str(tmp_path / 'killed')
  proc = launch(workdir, seeds)
  ckpt_dir = os.path.join(workdir, 'seed1', 'checkpoints')
  deadline = time.time() + 600
  while time.time() < deadline and proc.poll() is None:  # Kill once seed 1 has step 80.
    if os.path.isdir(ckpt_dir) and '80' in os.listdir(ckpt_dir):
      break
    time.sleep(0.02)
  assert proc.poll() is None, 'the run ended before it could be killed'
  os.kill(proc.pid, signal.SIGKILL)
  proc.wait()
  resumed = launch(workdir, seeds)
  _, err = resumed.communicate(timeout=900)
  assert resumed.returncode == 0, err[-2000:]
  for seed in ('seed0', 'seed1'):
    got = _buffer(os.path.join(workdir, seed), ENV_STEPS)
    want = _buffer(os.path.join(whole, seed), ENV_STEPS)
    for name in ('observations', 'actions', 'rewards', 'episode_lengths'):
      np.testing.assert_allclose(getattr(got, name), getattr(want, name), atol=1e-5,
                                 err_msg=f'{seed} {name}')
    assert got.metadata['sampler_rng'] == want.metadata['sampler_rng'], seed
  assert not np.allclose(_buffer(os.path.join(workdir, 'seed0'), ENV_STEPS).actions,
                         _buffer(os.path.join(workdir, 'seed1'), ENV_STEPS).actions)
  with open(os.path.join(workdir, 'pooled.json')) as f:
    assert json.load(f)['seeds'] == [0, 1]
