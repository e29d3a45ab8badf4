"""Online training at smoke size: acting, buffer, updates, checkpoints, SIGKILL and resume, noise.

The runs go through the launcher in subprocesses that share the session's compilation cache.
"""

import json
import os
import signal
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments.configs import door_open_online
from ld_mpc_jax import checkpointing, data, evaluation_suite, online, run_files
from ld_mpc_jax.models import init_params
from ld_mpc_jax.planner import make_plan

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV_STEPS = 200  # Five waves of 2 episodes x 20 environment steps; the first one random.


@pytest.fixture(scope='module')
def launch():
  """launch(workdir) -> Popen of the smoke online job (no evaluation).

  The subprocesses inherit the session's compilation cache (conftest.py), so the update and the
  planner compile once for all of them.
  """
  def start(workdir):
    cmd = [sys.executable, '-m', 'experiments.train', '--config=door_open_online.py:smoke',
           f'--workdir={workdir}', f'--config.online.env_steps={ENV_STEPS}',
           '--config.eval.episodes=0']
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
  return data.load(online.buffer_path(workdir, step))


@pytest.mark.long  # Its fixture runs the smoke job.
def test_smoke_run_acts_fills_the_buffer_updates_and_checkpoints(finished):
  waves = run_files.read_csv(os.path.join(finished, online.ONLINE_CSV))
  assert [int(w['env_steps']) for w in waves] == [40, 80, 120, 160, 200]
  assert [w['acting'] for w in waves] == ['random'] + ['planner'] * 4
  # update_ratio 0.1: floor(0.1 x environment steps) updates, none before the seed wave is in.
  assert [int(w['updates']) for w in waves] == [0, 8, 12, 16, 20]
  ds = _buffer(finished, ENV_STEPS)
  assert ds.num_episodes == 10 and list(ds.episode_lengths) == [10] * 10  # 10 decisions each.
  assert ds.metadata['online'] == dict(env_steps=200, updates=20, episodes=10, normalized=True,
                                       train_seconds=ds.metadata['online']['train_seconds'])
  assert np.all(np.abs(ds.actions) <= 1.0) and np.all(np.isfinite(ds.observations))
  manager = checkpointing.checkpoint_manager(finished)
  assert manager.all_steps() == [120, 160, 200]  # train.max_checkpoints = 3, at environment steps.
  assert sorted(os.listdir(os.path.join(finished, online.BUFFER_DIR))) == [
      'buffer_120.npz', 'buffer_160.npz', 'buffer_200.npz']  # Each beside its orbax step.
  config, _, step = checkpointing.load_for_evaluation(finished)
  assert step == 20 and config.online.enabled  # TrainState.step counts updates.
  losses = run_files.read_csv(os.path.join(finished, online.LOSSES_CSV))
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
  waves = run_files.read_csv(os.path.join(workdir, online.ONLINE_CSV))
  assert int(waves[-1]['env_steps']) == ENV_STEPS


def test_exploration_noise_only_when_acting(tmp_path, monkeypatch):
  config = door_open_online.get_config('smoke')
  config.online.env_steps = 80  # The seed wave and one planner wave.
  config.online.eval_every = 40
  config.eval.splits = ('held_out',)
  config.eval.baselines = ()
  used = []  # (acting or evaluating, plan noise stds) of every planner policy built.

  def recording(where, original):
    def make(cfg, params, mode='plan', **kwargs):
      used.append((where, mode, cfg.plan.action_noise_std, cfg.plan.prior_noise_std))
      return original(cfg, params, mode, **kwargs)
    return make
  monkeypatch.setattr(online, 'BatchAgentPolicy', recording('act', online.BatchAgentPolicy))
  monkeypatch.setattr(evaluation_suite, 'BatchAgentPolicy',
                      recording('eval', evaluation_suite.BatchAgentPolicy))
  # No learning needed here: an update that only counts (and compiles in no time).
  monkeypatch.setattr(online, 'make_update', lambda cfg: lambda state, batch, key: (
      state.replace(step=state.step + 1), {'loss': jnp.float32(1.0)}))
  online.train_online(config, str(tmp_path / 'run'))
  assert ('act', 'plan', 0.2, 0.2) in used
  evaluations = [u for u in used if u[0] == 'eval']
  assert evaluations and all(u[2:] == (0.0, 0.0) for u in evaluations)
  assert all(u[2:] == (0.2, 0.2) for u in used if u[0] == 'act')
  # The acting planner's candidates are the plain planner's plus noise, same key and params.
  acting = online.acting_config(config)
  params = init_params(config, jax.random.key(0))
  z = jax.random.normal(jax.random.key(1), (config.model.latent_dim,))
  noisy = make_plan(acting)(params, z, jax.random.key(2)).candidates
  plain = make_plan(config)(params, z, jax.random.key(2)).candidates
  assert config.plan.action_noise_std == 0.0 and acting.plan.action_noise_std == 0.2
  assert float(jnp.abs(noisy - plain).max()) > 0.05
  assert float(jnp.abs(noisy).max()) <= 1.0


@pytest.mark.parametrize('override,match', [
    ('--config.online.init_from=/nonexistent/run', 'init_from'),
    ('--config.online.update_ratio=-1', 'update_ratio'),
    ('--config.online.seed_steps=0', 'seed_steps'),
])
def test_bad_online_config_exits_2_with_one_line(tmp_path, override, match):
  done = subprocess.run([sys.executable, '-m', 'experiments.train',
                         '--config=door_open_online.py:smoke', f'--workdir={tmp_path}', override],
                        cwd=REPO, capture_output=True, text=True, timeout=120)
  assert done.returncode == 2
  lines = done.stderr.strip().splitlines()
  assert len(lines) == 1 and lines[0].startswith('error:') and match in lines[0]


@pytest.mark.parametrize('overrides, match', [
    (dict(reward='sparse', init_from='runs/x'), 'mix the offline'),
    (dict(reward='shaped'), "'dense' or 'sparse'"),
    (dict(updates_per_call=0), 'updates_per_call must be an integer'),
    (dict(exec_noise_start=-0.1), 'must be >= 0'),
])
def test_acting_settings_are_checked(overrides, match):
  from ld_mpc_jax.config_checks import validate_config
  c = door_open_online.get_config('smoke')
  c.online.update(overrides)
  with pytest.raises(ValueError, match=match):
    validate_config(c)


def test_executed_noise_anneals_linearly():
  c = door_open_online.get_config('cpu')
  start, end = c.online.exec_noise_start, c.online.exec_noise_end
  assert online.executed_noise(c, 0, 1_600) == pytest.approx(start)  # Before learning starts.
  assert online.executed_noise(c, 1_600, 1_600) == pytest.approx(start)
  mid = (1_600 + c.online.env_steps) // 2
  assert online.executed_noise(c, mid, 1_600) == pytest.approx((start + end) / 2)
  assert online.executed_noise(c, c.online.env_steps, 1_600) == pytest.approx(end)
