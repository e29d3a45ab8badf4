"""experiments.train: unknown presets and an online batch the seed data cannot fill end in one
line and exit code 2, before any work starts."""

import os
import re
import subprocess
import sys

import numpy as np
import pytest

from experiments.configs import door_open_online
from ld_mpc_jax import data
from ld_mpc_jax import config_checks

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


def _seed_windows(config) -> int:
  """Windows of the real sampler over the seed waves' episodes (random data of their lengths)."""
  o = config.online
  waves = -(-o.seed_steps // (o.num_envs * o.episode_steps))
  decisions = -(-o.episode_steps // config.eval.action_repeat)
  rng = np.random.default_rng(0)
  episodes = [dict(obs=rng.normal(size=(decisions + 1, config.obs_dim)).astype(np.float32),
                   action=rng.uniform(-1, 1, (decisions, config.action_dim)).astype(np.float32),
                   reward=np.zeros(decisions, np.float32), success=np.zeros(decisions, bool))
              for _ in range(waves * o.num_envs)]
  return data.ReplayBuffer(data.Dataset.from_episodes(episodes), config.horizon + 2).num_windows


@pytest.mark.parametrize('seed_steps', [40, 41, 80])  # 1, 2 and 2 seed waves of 40 steps.
def test_online_batch_may_be_at_most_the_seed_windows(seed_steps):
  config = door_open_online.get_config('smoke')
  config.online.seed_steps = seed_steps
  windows = _seed_windows(config)
  assert windows == 12 * -(-seed_steps // 40)
  config.train.batch_size = windows
  config_checks.validate_config(config)
  config.train.batch_size = windows + 1
  with pytest.raises(ValueError, match=f'batch_size \\({windows + 1}\\).*{windows} windows'):
    config_checks.validate_config(config)


def test_online_batch_is_not_checked_without_seed_updates():
  config = door_open_online.get_config('smoke')
  config.train.batch_size = 1000
  with pytest.raises(ValueError, match='batch_size'):
    config_checks.check_online_budget(config)
  config.online.env_steps = config.online.seed_steps  # The run ends before its first update.
  config_checks.check_online_budget(config)
  config.online.env_steps, config.online.update_ratio = 120, 0.0  # No update at all.
  config_checks.check_online_budget(config)
  config.online.update_ratio, config.online.init_from = 0.1, '/runs/offline'  # Its dataset:
  config_checks.check_online_budget(config)  # checked at start (runs.check_config_for_data).
