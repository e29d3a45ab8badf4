"""Several training seeds in one online run (`train.num_seeds`): each seed's run is the one it
makes alone (parameters to float tolerance, the same episodes), and the seeds differ."""

import json
import os

import jax
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open_online
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import LearnSettings
from ld_mpc_jax import data
from ld_mpc_jax.data import online_buffer
from ld_mpc_jax.runs import train


def _config(seed, num_seeds):
  config = door_open_online.get_config('smoke')
  config.seed, config.train.num_seeds = seed, num_seeds
  config.online.env_steps = 80  # The random seed wave and one wave acting with the planner.
  config.eval.episodes = 0  # Train and checkpoint only.
  return config


def _params(workdir, config):
  target = checkpointing.abstract_state(LearnSettings.from_config(config))
  return checkpointing.restore_latest(checkpointing.checkpoint_manager(workdir), target).params


def _episodes(workdir):
  ds = data.load(online_buffer.buffer_path(workdir, 80))
  return [ds.episode(e) for e in range(ds.num_episodes)]


@pytest.fixture(scope='module')
def runs(build_once):
  """Seeds 0 and 1 in one run, and seed 1 alone: trained once for every xdist worker."""
  def build(root):
    train.train_and_evaluate(_config(0, 2), str(root / 'both'))
    train.train_and_evaluate(_config(1, 1), str(root / 'alone1'))
  return build_once('online_seeds', build)


def test_a_seed_trained_beside_another_is_the_seed_trained_alone(runs):
  together, alone = str(runs / 'both' / 'seed1'), str(runs / 'alone1')
  assert sorted(os.listdir(runs / 'both')) == ['pooled.json', 'pooled.md', 'seed0', 'seed1']
  saved = checkpointing.load_config(together)
  assert (saved.seed, saved.train.num_seeds) == (1, 1)  # As a run of seed 1 alone saves it.
  ours, theirs = _params(together, _config(1, 1)), _params(alone, _config(1, 1))
  for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(ours),
                          jax.tree_util.tree_leaves(theirs), strict=True):
    # An attention key's bias has zero gradient (softmax ignores a shift shared by all keys):
    # Adam turns its rounding noise into steps of up to the learning rate (1e-4, 8 updates).
    atol = 1e-3 if "['key']['bias']" in jax.tree_util.keystr(path) else 1e-5
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=atol, err_msg=jax.tree_util.keystr(path))
  for name in ('losses.csv', 'online.csv'):  # Losses of the last update; training episodes.
    rows = [np.genfromtxt(os.path.join(d, name), delimiter=',', names=True)
            for d in (together, alone)]
    for field in rows[0].dtype.names:
      if field != 'env_steps_per_s':
        np.testing.assert_allclose(rows[0][field], rows[1][field], rtol=1e-4, atol=1e-9,
                                   err_msg=field)
  for a, b in zip(_episodes(together), _episodes(alone), strict=True):
    np.testing.assert_allclose(a['action'], b['action'], atol=1e-5)
    np.testing.assert_allclose(a['obs'], b['obs'], atol=1e-5)


def test_the_seeds_of_one_run_are_independent(runs):
  first, second = (_episodes(str(runs / 'both' / f'seed{s}')) for s in (0, 1))
  assert not np.allclose(first[0]['action'], second[0]['action'])
  p0, p1 = (_params(str(runs / 'both' / f'seed{s}'), _config(s, 1)) for s in (0, 1))
  assert not np.allclose(jax.tree_util.tree_leaves(p0)[0], jax.tree_util.tree_leaves(p1)[0])


def test_updates_dispatched_before_the_environments_step_are_the_updates_made_after(
    runs, tmp_path, monkeypatch):
  """The environment loop off the critical path changes nothing: seed 1 trained with every
  update waiting for the steps that call for it (the order before) ends on the same bits."""
  from ld_mpc_jax.online import seats as online_seats  # pylint: disable=g-import-not-at-top
  made = []
  monkeypatch.setattr(online_seats.SeatWave, 'upcoming', lambda self: made.append(0) or 0)
  train.train_and_evaluate(_config(1, 1), str(tmp_path / 'waiting'))
  assert made  # The planner's decisions asked, and no update was dispatched ahead.
  ours, theirs = (_params(d, _config(1, 1)) for d in (str(runs / 'alone1'), str(tmp_path / 'waiting')))
  for a, b in zip(jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(theirs), strict=True):
    np.testing.assert_array_equal(a, b)
  for a, b in zip(_episodes(str(runs / 'alone1')), _episodes(str(tmp_path / 'waiting')), strict=True):
    np.testing.assert_array_equal(a['action'], b['action'])


def test_the_next_decision_takes_action_repeat_steps_until_the_limit():
  from ld_mpc_jax.envs.metaworld_env import make_env  # pylint: disable=g-import-not-at-top
  env = make_env('door-open-v3', seed=0, action_repeat=2, max_episode_steps=5)
  assert env.next_substeps() == 0  # Not reset.
  env.reset()
  taken = []
  while True:
    expected = env.next_substeps()
    *_, terminated, truncated, info = env.step(np.zeros(4, np.float32))
    taken.append((expected, info['substeps']))
    if terminated or truncated:
      break
  assert taken == [(2, 2), (2, 2), (1, 1)]
  assert env.next_substeps() == 0


# Two seeds on two (virtual CPU) devices, one program per device (`train.seed_devices`).
_TWO_DEVICES = r'''
import json, sys
import jax
jax.config.update('jax_num_cpu_devices', 2)
sys.path.insert(0, 'tests')
from test_online_seeds import _config
from ld_mpc_jax.runs import train
config = _config(0, 2)
config.train.seed_devices = 2
train.train_and_evaluate(config, sys.argv[1])
print(json.dumps(dict(devices=len(jax.local_devices()))))
'''


@pytest.mark.long  # Compiles every program again for two devices; the grouping: test_seed_groups.py.
def test_seeds_on_two_devices_are_the_seeds_on_one(runs, tmp_path):
  """Seeds 0 and 1 on two devices (a group each, dispatched side by side) end where seed 1
  trained alone and seed 0 trained beside seed 1 on one device end."""
  import subprocess, sys  # pylint: disable=g-import-not-at-top,multiple-imports
  repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  env = dict(os.environ, JAX_PLATFORMS='cpu', PYTHONPATH=repo)
  done = subprocess.run([sys.executable, '-c', _TWO_DEVICES, str(tmp_path / 'two')], cwd=repo,
                        env=env, capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  assert json.loads(done.stdout.strip().splitlines()[-1]) == dict(devices=2)
  for seed, other in ((0, runs / 'both' / 'seed0'), (1, runs / 'alone1')):
    ours = _params(str(tmp_path / 'two' / f'seed{seed}'), _config(seed, 1))
    theirs = _params(str(other), _config(seed, 1))
    for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(ours),
                            jax.tree_util.tree_leaves(theirs), strict=True):
      atol = 1e-3 if "['key']['bias']" in jax.tree_util.keystr(path) else 1e-5
      np.testing.assert_allclose(a, b, rtol=1e-4, atol=atol, err_msg=jax.tree_util.keystr(path))
    for a, b in zip(_episodes(str(tmp_path / 'two' / f'seed{seed}')), _episodes(str(other)),
                    strict=True):
      np.testing.assert_allclose(a['action'], b['action'], atol=1e-5)
