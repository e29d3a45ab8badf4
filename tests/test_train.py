"""The offline job at smoke size: train, checkpoint, evaluate, report; faults; a crash and its
resume in-process. (SIGKILL and resume through the launcher, in subprocesses:
tests/e2e/test_train_resume.py, marked long.)"""

import json
import os

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import LearnSettings
from ld_mpc_jax.eval import run_files
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.runs import loop as runs, train, train_seeds
from ld_mpc_jax.ops import stats
from ld_mpc_jax.data import replay


@pytest.fixture(scope='module')
def data_dir(tmp_path_factory):
  return str(tmp_path_factory.mktemp('data'))


def smoke(data_dir, **train_overrides):
  c = door_open.get_config('smoke')
  c.data.dir = data_dir
  for k, v in train_overrides.items():
    c.train[k] = v
  return c


def test_smoke_run_end_to_end(tmp_path, data_dir):
  workdir = str(tmp_path / 'run')
  report = train.train_and_evaluate(smoke(data_dir), workdir)
  for key in ('success_rate', 'success_ci95', 'mean_return', 'decisions_per_s',
              'train_seconds', 'steps', 'config', 'versions', 'git_commit'):
    assert key in report, key
  assert report['steps'] == 4
  # The headline numbers are the held-out planner episodes' of episodes.csv (one episode here).
  rows = run_files.read_csv(os.path.join(workdir, 'episodes.csv'))
  held = [r for r in rows if (r['split'], r['policy']) == ('held_out', 'plan')]
  k = sum(int(r['success']) for r in held)
  assert len(held) == 1 and report['success_rate'] == k / len(held)
  assert list(report['success_ci95']) == pytest.approx(list(stats.wilson_interval(k, len(held))))
  assert report['mean_return'] == pytest.approx(float(held[0]['return']))
  assert report['decisions_per_s'] > 0
  assert set(report['baselines']) == {'actor', 'proposal'}
  assert report['config']['task'] == 'door-open-v3'
  with open(os.path.join(workdir, 'report.json')) as f:
    assert json.load(f)['steps'] == 4
  for name in ('report.md', 'metrics.csv', 'eval.csv', 'losses.png', 'config.json'):
    assert os.path.getsize(os.path.join(workdir, name)) > 0, name
  assert os.listdir(os.path.join(workdir, 'tb'))
  # The evaluation entry point reloads the run.
  config, params, step = checkpointing.load_for_evaluation(workdir)
  assert step == 4 and config.model.width == 16
  # The observation normalisation is the dataset's, and travels with the checkpoint.
  from ld_mpc_jax import data
  d = config.data
  ds = data.get_or_collect(config.task, d.preset, d.episodes, d.seed, d.dir, action_repeat=2)
  np.testing.assert_allclose(params['encoder']['obs_mean'], ds.observations.mean(0), rtol=1e-4,
                             atol=1e-5)
  assert 'critics' in params
  result = runs.run_evaluation(EvalSpec.from_config(config), params, 'actor', 1, seed=0)
  assert result['num_episodes'] == 1
  # Both goal splits, held-out first, every policy on the same episodes, records on disk.
  assert list(report['evaluation']) == ['held_out', 'train']
  for split in report['evaluation'].values():
    assert list(split['policies']) == ['plan', 'actor', 'proposal']
    assert split['paired']['plan vs actor']['n'] == 1
  assert len(rows) == 2 * 3 and {r['split'] for r in rows} == {'held_out', 'train'}
  assert report['success_rate'] == float(rows[0]['success'])  # Held-out planner first.
  assert 'McNemar' in open(os.path.join(workdir, 'report.md')).read()


def test_non_finite_loss_stops_and_keeps_last_good_checkpoint(tmp_path, data_dir, monkeypatch):
  original = replay.ReplayBuffer.sample
  calls = [0]
  def poisoned(self, batch_size):
    batch = original(self, batch_size)
    calls[0] += 1
    if calls[0] >= 3:  # Steps 3 and 4 see NaN rewards.
      batch['reward'] = np.full_like(batch['reward'], np.nan)
    return batch
  monkeypatch.setattr(replay.ReplayBuffer, 'sample', poisoned)
  workdir = str(tmp_path / 'run')
  with pytest.raises(FloatingPointError, match='non-finite loss'):
    train.train_and_evaluate(smoke(data_dir), workdir)
  manager = checkpointing.checkpoint_manager(workdir)
  assert manager.latest_step() == 2
  assert not os.path.exists(os.path.join(workdir, 'report.json'))


class _Crash(Exception):
  """Stands in for a crash in the middle of training."""


def test_a_crashed_run_resumes_from_its_last_checkpoint_to_the_final_step(
    tmp_path, data_dir, monkeypatch, unevaluated_runs):
  original = replay.ReplayBuffer.sample
  calls = [0]
  def crashing(self, batch_size):
    calls[0] += 1
    if calls[0] == 4:  # A checkpoint at step 2; the crash comes in the middle of the last step.
      raise _Crash
    return original(self, batch_size)
  monkeypatch.setattr(replay.ReplayBuffer, 'sample', crashing)
  # The smoke run's 4 steps (the update compiled by the other tests of this file), a checkpoint
  # every 2, a log row every step.
  c = smoke(data_dir, checkpoint_every=2, log_every=1, eval_every=1000)
  c.eval.episodes = 0  # Resuming is tested here; evaluation elsewhere.
  workdir = str(tmp_path / 'run')
  with pytest.raises(_Crash):
    train.train_and_evaluate(c, workdir)
  assert checkpointing.checkpoint_manager(workdir).latest_step() == 2
  assert not os.path.exists(os.path.join(workdir, 'report.json'))
  monkeypatch.setattr(replay.ReplayBuffer, 'sample', original)
  report = train.train_and_evaluate(c, workdir)
  assert report['steps'] == 4 and report['steps_this_run'] == 2
  assert checkpointing.load_for_evaluation(workdir)[2] == 4
  steps = [int(r['step']) for r in run_files.read_csv(os.path.join(workdir, 'metrics.csv'))]
  assert steps == [1, 2, 3, 4]  # Row 3 of the crashed run is not kept twice.
  # It trained on the windows of an uninterrupted run (its sampler continued past step 2), and
  # ends on its parameters, bit for bit (logging and evaluation intervals change nothing).
  import jax
  got = checkpointing.load_for_evaluation(workdir)[1]
  want = checkpointing.load_for_evaluation(unevaluated_runs['a'][0])[1]
  assert all(jax.tree_util.tree_leaves(jax.tree_util.tree_map(
      lambda x, y: np.array_equal(np.asarray(x), np.asarray(y)), got, want)))


@pytest.mark.parametrize('field,value,match', [
    ('task', 'door-openn-v3', 'door-openn-v3'),
    ('horizon', 400, 'horizon'),
    ('train.batch_size', 10_000_000, 'batch_size'),
    ('plan.num_candidates', 0, 'num_candidates'),
])
def test_bad_config_fails_before_compilation(tmp_path, data_dir, monkeypatch, field, value,
                                             match):
  def no_compile(*args, **kwargs):
    raise AssertionError('compiled before the config was checked')
  monkeypatch.setattr(train, 'make_update', no_compile)
  c = smoke(data_dir)
  node, *rest = field.split('.')
  if rest:
    c[node][rest[0]] = value
  else:
    c[node] = value
  with pytest.raises(ValueError, match=match):
    train.train_and_evaluate(c, str(tmp_path / 'run'))


@pytest.fixture(scope='module')
def unevaluated_runs(build_once, data_dir):
  """Two runs of one config and seed with `eval.episodes = 0`: {name: (workdir, report)}.
  Shared by the tests below (and the xdist workers), so the suite trains them once."""
  def build(root):
    for name in ('a', 'b'):
      c = smoke(data_dir)
      c.eval.episodes = 0
      train.train_and_evaluate(c, str(root / name))
  root = build_once('unevaluated_runs', build)
  out = {}
  for name in ('a', 'b'):
    with open(root / name / 'report.json') as f:
      out[name] = (str(root / name), json.load(f))
  return out


def test_eval_episodes_zero_trains_without_evaluating(unevaluated_runs):
  workdir, report = unevaluated_runs['a']
  assert report['steps'] == 4 and report['success_rate'] is None and report['baselines'] == {}
  assert not os.path.exists(os.path.join(workdir, 'eval.csv'))


@pytest.mark.parametrize('steps_per_s,made,expected', [
    (4.671, 4000, '4.67 steps/s without compilation'),
    (float('nan'), 0, 'no update steps in this run: resumed at the final step'),
    (float('nan'), 1, '1 update step in this run, too few to time without compilation'),
    (float('nan'), 2, '2 update steps in this run, too few to time without compilation')])
def test_report_summary_states_speed_or_that_nothing_was_trained(steps_per_s, made, expected):
  from ld_mpc_jax.eval import evaluation_suite
  records = [dict(run=0, policy=mode, split='held_out', eval_seed=0, episode=i,
                  success=int(i < k), decisions_per_s=30.5, **{'return': 474.7})
             for mode, k in (('plan', 47), ('actor', 40)) for i in range(50)]
  report = dict(task='door-open-v3', steps=4000, train_seconds=836.2, steps_per_s=steps_per_s,
                steps_this_run=made,
                num_params=1423442, eval_episodes=50, eval_seeds=[0], git_commit='abc',
                evaluation=evaluation_suite.summarize(records))
  md = train._summary_md(report)
  assert f'4000 update steps in 836 s of training ({expected}); 1,423,442 parameters.' in md
  assert '| held_out | planner | 47/50 = 0.94 | [0.84, 0.98] | 0.94 | 474.7 | 30.5 |' in md
  # 7 episodes only the planner solved, none only the actor: p = 2 / 2^7.
  assert '| held_out | planner vs actor prior | 50 | 7 | 0 | 0.0156 |' in md
  assert 'nan' not in md


def test_same_seed_trains_bit_identical_parameters(unevaluated_runs):
  """Two runs of one config and seed on one machine agree to the bit (results can be re-run)."""
  import jax
  params = [checkpointing.load_for_evaluation(unevaluated_runs[name][0])[1] for name in 'ab']
  diffs = jax.tree_util.tree_map(lambda x, y: float(np.max(np.abs(np.asarray(x) - np.asarray(y)))),
                                 *params)
  assert max(jax.tree_util.tree_leaves(diffs)) == 0.0


def test_packed_run_evaluates_as_trained_and_holds_no_training_state(unevaluated_runs, tmp_path):
  import tarfile
  import jax
  from ld_mpc_jax.cli import pack_runs
  workdir, _ = unevaluated_runs['a']
  path = pack_runs.pack(workdir, str(tmp_path / 'out'))
  assert os.path.basename(path) == 'a.tgz'
  with tarfile.open(path) as t:
    t.extractall(tmp_path / 'unpacked')
  packed = str(tmp_path / 'unpacked' / 'a')
  config, ema, step = checkpointing.load_for_evaluation(packed)
  _, original, original_step = checkpointing.load_for_evaluation(workdir)
  assert step == original_step == 4 and config.seed == 0
  for x, y in zip(jax.tree.leaves(ema), jax.tree.leaves(original)):
    np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
  assert np.any(np.asarray(jax.tree.leaves(ema)[0]))
  learn = LearnSettings.from_config(config)
  state = checkpointing.restore_latest(checkpointing.checkpoint_manager(packed),
                                       checkpointing.abstract_state(learn))
  assert not any(np.any(np.asarray(x)) for x in jax.tree.leaves(state.params))
  empty = tmp_path / 'empty'
  os.makedirs(empty / 'checkpoints')
  with open(empty / 'config.json', 'w') as f:
    f.write(open(os.path.join(workdir, 'config.json')).read())
  assert pack_runs.pack(str(empty), str(tmp_path / 'out')) is None


def test_training_into_a_workdir_of_another_config_writes_nothing(tmp_path, data_dir,
                                                                  monkeypatch):
  workdir = tmp_path / 'run'
  checkpointing.save_config(smoke(data_dir), str(workdir))
  before = (workdir / checkpointing.CONFIG_FILE).read_text()
  monkeypatch.setattr(train.data, 'load_dataset', lambda spec: 1 / 0)  # No work before the check.
  with pytest.raises(checkpointing.WorkdirError, match=r'train.learning_rate \(.* -> 0.5\)'):
    train.train_and_evaluate(smoke(data_dir, learning_rate=0.5), str(workdir))
  assert os.listdir(workdir) == [checkpointing.CONFIG_FILE]
  assert (workdir / checkpointing.CONFIG_FILE).read_text() == before


def test_rerunning_a_finished_run_changes_nothing(unevaluated_runs, tmp_path, data_dir,
                                                  monkeypatch, capsys):
  """Issue 102: a finished run run again appended a duplicate final row and replaced its
  steps/s; now it says it is finished, returns its report, and writes nothing."""
  import shutil
  workdir = tmp_path / 'a'
  shutil.copytree(unevaluated_runs['a'][0], workdir)
  before = {p: p.read_bytes() for p in workdir.rglob('*') if p.is_file()}
  monkeypatch.setattr(train, 'make_update', lambda *a, **k: pytest.fail('trained again'))
  monkeypatch.setattr(train_seeds, 'make_seeds_update',
                      lambda *a, **k: pytest.fail('trained again'))
  with open(workdir / 'config.json') as f:  # The xdist worker that built it had its own data dir.
    c = smoke(json.load(f)['data']['dir'])
  c.eval.episodes = 0
  report = train.train_and_evaluate(c, str(workdir))
  assert report.pop('records') == [] and report == unevaluated_runs['a'][1]  # Not evaluated.
  assert 'finished: nothing to do, nothing changed' in capsys.readouterr().err
  assert {p: p.read_bytes() for p in workdir.rglob('*') if p.is_file()} == before
