"""Several training seeds of an offline run in one process (`train.num_seeds`, offline): each seed
ends where it ends alone, and a run killed between two seeds' checkpoints resumes both from the
step they share, to the same parameters."""

import os
import shutil

import jax
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import LearnSettings
from ld_mpc_jax.runs.train import train_and_evaluate


def _config(seed, num_seeds):
  config = door_open.get_config('smoke')
  config.seed, config.train.num_seeds = seed, num_seeds
  config.train.num_steps, config.train.checkpoint_every = 4, 2
  config.eval.episodes = 0  # Train and checkpoint only.
  return config


def _params(workdir, seed):
  target = checkpointing.abstract_state(LearnSettings.from_config(_config(seed, 1)))
  return checkpointing.restore_latest(checkpointing.checkpoint_manager(workdir), target).params


@pytest.fixture(scope='module')
def runs(build_once):
  """Seeds 0 and 1 in one run, and seed 1 alone: trained once for every xdist worker."""
  def build(root):
    train_and_evaluate(_config(0, 2), str(root / 'both'))
    train_and_evaluate(_config(1, 1), str(root / 'alone1'))
  return build_once('offline_seeds', build)


def _close(a_tree, b_tree):
  for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(a_tree),
                          jax.tree_util.tree_leaves(b_tree), strict=True):
    # An attention key's bias has zero gradient: Adam turns its rounding noise into steps of up
    # to the learning rate (tests/test_online_seeds.py).
    atol = 1e-3 if "['key']['bias']" in jax.tree_util.keystr(path) else 1e-5
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=atol, err_msg=jax.tree_util.keystr(path))


def test_a_seed_trained_beside_another_is_the_seed_trained_alone(runs):
  assert {'seed0', 'seed1', 'pooled.json', 'pooled.md'} <= set(os.listdir(runs / 'both'))
  saved = checkpointing.load_config(str(runs / 'both' / 'seed1'))
  assert (saved.seed, saved.train.num_seeds) == (1, 1)  # As a run of seed 1 alone saves it.
  _close(_params(str(runs / 'both' / 'seed1'), 1), _params(str(runs / 'alone1'), 1))
  rows = [np.genfromtxt(os.path.join(d, 'metrics.csv'), delimiter=',', names=True)
          for d in (runs / 'both' / 'seed1', runs / 'alone1')]
  np.testing.assert_allclose(rows[0]['loss'], rows[1]['loss'], rtol=1e-4)
  p0, p1 = _params(str(runs / 'both' / 'seed0'), 0), _params(str(runs / 'both' / 'seed1'), 1)
  assert not np.allclose(jax.tree_util.tree_leaves(p0)[0], jax.tree_util.tree_leaves(p1)[0])


def test_a_run_killed_between_two_seeds_checkpoints_resumes_from_the_step_they_share(
    runs, tmp_path):
  work = tmp_path / 'both'
  shutil.copytree(runs / 'both', work)
  shutil.rmtree(work / 'seed1' / 'checkpoints' / '4')  # Seed 0 saved step 4, seed 1 did not.
  train_and_evaluate(_config(0, 2), str(work))
  for seed in (0, 1):
    assert checkpointing.checkpoint_manager(str(work / f'seed{seed}')).latest_step() == 4
    a, b = _params(str(work / f'seed{seed}'), seed), _params(str(runs / 'both' / f'seed{seed}'), seed)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
      np.testing.assert_array_equal(x, y)  # The same windows and keys from step 2 on.


_TWO_DEVICES = r'''
import sys
import jax
jax.config.update('jax_num_cpu_devices', 2)
sys.path.insert(0, 'tests')
from test_train_seeds import _config
from ld_mpc_jax.runs.train import train_and_evaluate
config = _config(0, 2)
config.train.seed_devices = 2
train_and_evaluate(config, sys.argv[1])
assert len(jax.local_devices()) == 2
'''


@pytest.mark.long  # Compiles every program again for two devices; the grouping: test_seed_groups.py.
def test_seeds_on_two_devices_end_where_they_end_on_one(runs, tmp_path):
  """Seeds 0 and 1 on two devices (one program each, `train.seed_devices`) end where seed 0
  beside seed 1 on one device and seed 1 alone end."""
  import subprocess, sys  # pylint: disable=g-import-not-at-top,multiple-imports
  repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  done = subprocess.run([sys.executable, '-c', _TWO_DEVICES, str(tmp_path / 'two')], cwd=repo,
                        env=dict(os.environ, JAX_PLATFORMS='cpu', PYTHONPATH=repo),
                        capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  _close(_params(str(tmp_path / 'two' / 'seed0'), 0), _params(str(runs / 'both' / 'seed0'), 0))
  _close(_params(str(tmp_path / 'two' / 'seed1'), 1), _params(str(runs / 'alone1'), 1))


def test_fine_tuning_from_a_run_of_several_seeds_starts_each_seed_from_its_own(runs, tmp_path):
  """`online.init_from` = a run of two offline seeds: online seed s starts from <run>/seed<s>,
  and its config (the one it saves) names that folder, as a run of seed s alone would."""
  from ld_mpc_jax import data  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.configs import door_open_online  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.runs import online  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.runs.seed_plan import seed_plans  # pylint: disable=g-import-not-at-top
  config = door_open_online.get_config('smoke')
  config.model.normalize_obs = True  # As the offline run's networks.
  config.train.num_seeds, config.online.init_from = 2, str(runs / 'both')
  source = online.check_init_from(seed_plans(config, ''))
  config.data.update(source.data.to_dict())
  job = online.online_job(seed_plans(config, str(tmp_path / 'ft')), data.load_dataset(data.DataSpec.from_config(config)))
  job.bar.close()
  assert [seat.run.plan.fields()['online']['init_from'] for seat in job.seats] == [
      str(runs / 'both' / f'seed{s}') for s in (0, 1)]
  (stack,) = job.learner.states  # One device: both seeds in one stack.
  for s in (0, 1):
    ours = jax.tree_util.tree_map(lambda x, s=s: np.asarray(x)[s], stack.params)
    for a, b in zip(jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(_params(
        str(runs / 'both' / f'seed{s}'), s)), strict=True):
      np.testing.assert_array_equal(a, b)
  one = tmp_path / 'one_seed'  # A folder with seed 0 only: seed 1's source is missing.
  shutil.copytree(runs / 'both' / 'seed0', one / 'seed0')
  config.online.init_from = str(one)
  with pytest.raises(ValueError, match='run of several seeds without seed1/'):
    online.check_init_from(seed_plans(config, ''))


def test_rerunning_a_finished_run_of_several_seeds_changes_nothing(runs, tmp_path, capsys):
  """Each seed's config and final checkpoint, and pooled.json: the run says it is finished and
  writes nothing (it restored both seeds and wrote every report again before)."""
  work = tmp_path / 'both'
  shutil.copytree(runs / 'both', work)
  before = {p: p.read_bytes() for p in work.rglob('*') if p.is_file()}
  report = train_and_evaluate(_config(0, 2), str(work))
  assert report['seeds'] == [0, 1]
  assert 'finished: nothing to do, nothing changed' in capsys.readouterr().err
  assert {p: p.read_bytes() for p in work.rglob('*') if p.is_file()} == before
  for seed in (0, 1):  # Checkpoints deleted after the run: still finished, not trained again.
    shutil.rmtree(work / f'seed{seed}' / 'checkpoints')
  train_and_evaluate(_config(0, 2), str(work))
  assert 'finished: nothing to do, nothing changed' in capsys.readouterr().err
