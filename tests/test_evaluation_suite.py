"""ld_mpc_jax.eval.evaluation_suite: pooled summaries, paired tests and tables of hand-built records;
the per-cell cache of `evaluate_checkpoint` (evaluations stubbed, no environment runs)."""

import dataclasses
import math
import os
import types

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import CacheKey, EvalSpec

Z95 = 1.959963984540054  # The 0.975 quantile of the standard normal.

# Two training runs x 5 held-out episodes, planner and actor prior on the same episodes.
PLAN = {0: [1, 1, 1, 0, 1], 1: [1, 0, 1, 1, 0]}  # 7/10; runs 0.8 and 0.6.
ACTOR = {0: [1, 0, 0, 0, 1], 1: [0, 1, 1, 1, 0]}  # 5/10.
DEPARTURES = {0: [0, 2, 0, 0, 1], 1: [0, 0, 0, 0, 0]}  # The planner's, 3 of 100 decisions.


def _records():
  out = []
  for policy, outcomes in (('plan', PLAN), ('actor', ACTOR)):
    for run, successes in outcomes.items():
      for episode, success in enumerate(successes):
        r = dict(run=run, split='held_out', eval_seed=run % 2, episode=episode, policy=policy,
                 success=success, length=10, env_steps=20, **{'return': 10.0 * success})
        if policy == 'plan':
          r.update(departures=DEPARTURES[run][episode], decisions_per_s=100.0 + 200.0 * run)
        out.append(r)
  # A second split seen later, the planner alone.
  out += [dict(run=0, split='train', eval_seed=0, episode=e, policy='plan', success=1, length=5,
               env_steps=10, **{'return': 1.0}) for e in range(2)]
  return out


def _wilson(k, n):
  """The Wilson score interval by its formula."""
  p, z2 = k / n, Z95 ** 2
  centre, half = p + z2 / (2 * n), Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
  return [(centre - half) / (1 + z2 / n), (centre + half) / (1 + z2 / n)]


def test_summarize_pools_counts_and_pairs_on_the_same_episodes():
  out = evaluation_suite.summarize(_records())
  assert list(out) == ['held_out', 'train']  # Splits, then policies, in the order first seen.
  held = out['held_out']
  assert list(held['policies']) == ['plan', 'actor']
  plan, actor = held['policies']['plan'], held['policies']['actor']
  assert (plan['successes'], plan['episodes'], plan['success_rate']) == (7, 10, 0.7)
  assert (actor['successes'], actor['episodes']) == (5, 10)
  np.testing.assert_allclose(plan['success_ci95'], _wilson(7, 10), rtol=1e-9)
  np.testing.assert_allclose(actor['success_ci95'], _wilson(5, 10), rtol=1e-9)
  assert plan['mean_return'] == pytest.approx(7.0) and plan['mean_length'] == 10
  assert plan['per_run']['rates'] == pytest.approx({'0': 0.8, '1': 0.6})
  assert plan['per_run']['mean'] == pytest.approx(0.7)
  assert plan['per_run']['std'] == pytest.approx(math.sqrt(0.02))  # ddof 1 of 0.8, 0.6.
  assert plan['per_eval_seed'] == pytest.approx({'0': 0.8, '1': 0.6})
  assert plan['departure_share'] == pytest.approx(3 / 100)
  assert 'departure_share' not in actor  # Its records carry no departures.
  assert plan['decisions_per_s'] == 200.0  # Median of five 100s and five 300s.
  assert np.isnan(actor['decisions_per_s'])
  # Planner alone: episodes 1, 2 of run 0 and 0 of run 1; actor alone: episode 1 of run 1.
  t = held['paired']['plan vs actor']
  assert (t['n'], t['a_only'], t['b_only']) == (10, 3, 1)
  assert t['p_value'] == pytest.approx(2 * (1 + 4) / 2 ** 4)  # Two-sided, 1 of 4 discordant.
  assert list(out['train']['policies']) == ['plan'] and out['train']['paired'] == {}
  assert out['train']['policies']['plan']['successes'] == 2


def test_markdown_rows_of_the_summary():
  md = evaluation_suite.markdown(evaluation_suite.summarize(_records()))
  lo, hi = _wilson(7, 10)
  assert (f'| held_out | planner | 7/10 = 0.70 | [{lo:.2f}, {hi:.2f}] | 0.80, 0.60 | 7.0 | '
          '200.0 |') in md.splitlines()
  lo, hi = _wilson(5, 10)
  assert (f'| held_out | actor prior | 5/10 = 0.50 | [{lo:.2f}, {hi:.2f}] | 0.40, 0.60 | 5.0 | '
          'not recorded |') in md.splitlines()
  assert '| held_out | planner vs actor prior | 10 | 3 | 1 | 0.625 |' in md.splitlines()
  assert md.count('| train |') == 1  # One policy: a row, no comparison.


def _stub_evaluations(monkeypatch):
  """evaluate_policy stubbed: 3 episodes whose successes depend on the mode and seed."""
  calls = []

  def fake(spec, params, mode, num_episodes, seed, split, obs_noise_std, progress):
    calls.append((mode, split, seed))
    records = [dict(split=split, eval_seed=seed, episode=i, policy=mode,
                    success=int(mode == 'plan' or i < seed), length=4) for i in range(num_episodes)]
    k = sum(r['success'] for r in records)
    return dict(successes=k, success_rate=k / num_episodes, success_ci95=[0.0, 1.0],
                decisions_per_s=50.0, records=records, outcomes=[])

  monkeypatch.setattr(evaluation_suite, 'evaluate_policy', fake)
  return calls


def test_evaluate_checkpoint_caches_every_cell(tmp_path, monkeypatch):
  calls = _stub_evaluations(monkeypatch)
  config, workdir, lines = door_open.get_config('smoke'), str(tmp_path), []
  spec = EvalSpec.from_config(config)
  grid = dict(step=4, modes=('plan', 'actor'), splits=('held_out',), seeds=(0, 2),
              num_episodes=3)
  records = evaluation_suite.evaluate_checkpoint(spec, None, workdir, run=7, log=lines.append,
                                                 progress=False, **grid)
  assert calls == [('plan', 'held_out', 0), ('actor', 'held_out', 0), ('plan', 'held_out', 2),
                   ('actor', 'held_out', 2)]
  assert len(records) == 12 and all(r['run'] == 7 and r['decisions_per_s'] == 50.0
                                    for r in records)
  assert lines[0] == ('planner, held_out goals, evaluation seed 0 (run 7): success 1.00 [0.00, 1.00] '
                      '(50 decisions/s)')
  assert len(os.listdir(os.path.join(workdir, 'evals'))) == 4
  # The same grid again: every cell from its file, the records as before, tagged with this run.
  again = evaluation_suite.evaluate_checkpoint(spec, None, workdir, run=8, log=lines.append,
                                               progress=False, **grid)
  assert len(calls) == 4 and len(lines) == 8
  # Each reused cell says so, with the same success as when it was evaluated.
  kept = [line.split(': success ')[1] for line in lines[4:]]
  assert [k.split(' (kept in ')[0] for k in kept] == [
      line.split(': success ')[1].split(' (50')[0] for line in lines[:4]]
  assert all(os.path.exists(k.split(' (kept in ')[1][:-1]) for k in kept)
  assert [r['success'] for r in again] == [r['success'] for r in records]
  assert all(r['run'] == 8 for r in again)
  # A changed input that changes the episodes (here the planner's K) is a new cell.
  config.plan.num_candidates += 1
  spec = EvalSpec.from_config(config)
  evaluation_suite.evaluate_checkpoint(spec, None, workdir, log=lines.append, progress=False,
                                       **grid)
  assert len(calls) == 8 and len(os.listdir(os.path.join(workdir, 'evals'))) == 8
  # So is any cell after a code change that raised the cache version.
  monkeypatch.setattr(evaluation_suite, 'CACHE_VERSION', evaluation_suite.CACHE_VERSION + 1)
  evaluation_suite.evaluate_checkpoint(spec, None, workdir, log=lines.append, progress=False,
                                       **grid)
  assert len(calls) == 12
  # Without a workdir nothing is cached.
  evaluation_suite.evaluate_checkpoint(spec, None, None, log=lines.append, progress=False,
                                       **grid)
  assert len(calls) == 16


# One cached cell: the planner on one split and seed, quietly.
_ONE_CELL = dict(step=4, modes=('plan',), splits=('held_out',), seeds=(0,), num_episodes=3,
                 log=lambda line: None, progress=False)


def test_cache_keys_ignore_fields_at_their_legacy_defaults(tmp_path, monkeypatch):
  calls = _stub_evaluations(monkeypatch)
  config, workdir, grid = door_open.get_config('smoke'), str(tmp_path), _ONE_CELL
  config.plan.safe_margin_scaling = 'none'  # The field's legacy value (its default is another).
  evaluation_suite.evaluate_checkpoint(EvalSpec.from_config(config), None, workdir, **grid)
  # A config without a field that has a legacy default (as before the field existed) is the
  # same cell: adding such a field at its no-change value keeps every cached evaluation. (Its
  # key: the settings of such a config are read with the field at that value.)
  older = door_open.get_config('smoke')
  del older.plan['safe_margin_scaling']
  assert older.data.path == ''
  del older.data['path']
  spec = dataclasses.replace(EvalSpec.from_config(config), key=CacheKey.from_config(older))
  evaluation_suite.evaluate_checkpoint(spec, None, workdir, **grid)
  assert len(calls) == 1
  # So is the config read back from a run's config.json (tuples come back as lists).
  checkpointing.save_config(config, str(tmp_path / 'run'))
  evaluation_suite.evaluate_checkpoint(
      EvalSpec.from_config(checkpointing.load_config(str(tmp_path / 'run'))), None, workdir,
      **grid)
  assert len(calls) == 1
  # The field at another value is another cell.
  config.plan.safe_margin_scaling = 'expected_max'
  evaluation_suite.evaluate_checkpoint(EvalSpec.from_config(config), None, workdir, **grid)
  assert len(calls) == 2


def test_key_seed_draws_other_keys_on_the_same_episodes(tmp_path, monkeypatch):
  """eval.key_seed: the policy's keys from another seed, the episodes from the evaluation seed;
  at its default (-1) every cached cell keeps its key."""
  seen = {}
  class Policy:
    def __init__(self, settings, params, mode, seed, chunk, mesh):
      seen['key_seed'] = seed
  def run_episodes(policy, eps, *args, **kwargs):
    seen['episodes'] = [e.reset_seed for e in eps]
    return [dict(success=1)], {}
  monkeypatch.setattr(evaluation_suite, 'BatchAgentPolicy', Policy)
  monkeypatch.setattr(evaluation_suite.evaluation, 'run_episodes', run_episodes)
  monkeypatch.setattr(evaluation_suite.evaluation, 'result', lambda records, info: records)
  monkeypatch.setattr(evaluation_suite, 'episodes',
                      lambda source, split, seed, n: [types.SimpleNamespace(reset_seed=10 * seed + i)
                                                      for i in range(n)])
  config = door_open.get_config('smoke')
  evaluation_suite.evaluate_policy(EvalSpec.from_config(config), None, 'plan', 2, seed=3)
  assert seen == dict(key_seed=3, episodes=[30, 31])
  config.eval.key_seed = 5
  evaluation_suite.evaluate_policy(EvalSpec.from_config(config), None, 'plan', 2, seed=3)
  assert seen == dict(key_seed=5, episodes=[30, 31])
  # The cache: a run saved before the field (read back with it at -1) finds the default's cell,
  # another key seed is another cell.
  calls = _stub_evaluations(monkeypatch)
  older = door_open.get_config('smoke')
  del older.eval['key_seed'], older['version']  # Saved before both existed.
  checkpointing.save_config(older, str(tmp_path / 'old_run'))
  older = checkpointing.load_config(str(tmp_path / 'old_run'))
  for c in (older, door_open.get_config('smoke'), config):
    evaluation_suite.evaluate_checkpoint(EvalSpec.from_config(c), None, str(tmp_path),
                                         **_ONE_CELL)
  assert len(calls) == 2


def test_cells_cached_by_version_2_are_found_at_version_3(tmp_path, monkeypatch):
  calls = _stub_evaluations(monkeypatch)
  config, workdir, grid = door_open.get_config('smoke'), str(tmp_path), _ONE_CELL
  monkeypatch.setattr(evaluation_suite, 'CACHE_VERSION', 2)
  spec = EvalSpec.from_config(config)
  first = evaluation_suite.evaluate_checkpoint(spec, None, workdir, **grid)
  [v2_file] = os.listdir(os.path.join(workdir, 'evals'))
  monkeypatch.setattr(evaluation_suite, 'CACHE_VERSION', 3)
  again = evaluation_suite.evaluate_checkpoint(spec, None, workdir, **grid)
  assert len(calls) == 1 and again == first
  assert os.listdir(os.path.join(workdir, 'evals')) == [v2_file]
  # A later version (raised because episodes changed) does not reuse them.
  monkeypatch.setattr(evaluation_suite, 'CACHE_VERSION', 4)
  evaluation_suite.evaluate_checkpoint(EvalSpec.from_config(config), None, workdir, **grid)
  assert len(calls) == 2


def test_train_split_needs_data_collected_on_mt1_goals(monkeypatch):
  source = EvalSpec.from_config(door_open.get_config('smoke')).goals
  monkeypatch.setattr(evaluation_suite, 'dataset_goals', lambda c: (np.zeros((2, 6)), 3))
  assert evaluation_suite.available_splits(source, ('held_out', 'train')) == ('held_out', 'train')
  monkeypatch.setattr(evaluation_suite, 'dataset_goals', lambda c: (np.zeros((2, 6)), None))
  assert evaluation_suite.available_splits(source, ('held_out', 'train')) == ('held_out',)
  assert evaluation_suite.available_splits(source, ('held_out',)) == ('held_out',)
  with pytest.raises(ValueError, match='train goal split needs data collected on MT1 goals'):
    evaluation_suite.available_splits(source, ('train',))


def _policy_records(policy, run, successes, departures=None):
  out = []
  for i, s in enumerate(successes):
    r = dict(policy=policy, run=run, task=None, split='held_out', eval_seed=0, episode=i,
             success=s, length=10)
    if departures is not None:
      r['departures'] = departures[i]
    out.append(r)
  return out


def test_table_pairs_per_run_and_counts_departures():
  # Run a: planner wins episodes 0, 1 and loses 2; run b: planner loses 0, 1, 2 (3 behind).
  records = (_policy_records('plan[x]', 'a', [1, 1, 0, 1], departures=[2, 0, 5, 0])
             + _policy_records('actor', 'a', [0, 0, 1, 1])
             + _policy_records('plan[x]', 'b', [0, 0, 0, 1], departures=[0, 0, 0, 1])
             + _policy_records('actor', 'b', [1, 1, 1, 1]))
  rows = {r['policy']: r for r in evaluation_suite.against_anchor(records)}
  plan = rows['plan[x]']
  assert (plan['successes'], plan['episodes']) == (4, 8)
  assert plan['per_run'] == [0.75, 0.25]
  assert plan['departure_share'] == pytest.approx(8 / 80)
  assert (plan['vs_anchor']['a_only'], plan['vs_anchor']['b_only']) == (2, 4)
  assert [(m['a_only'], m['b_only']) for m in plan['vs_anchor_per_run']] == [(2, 1), (0, 3)]
  assert plan['most_behind'] == 3
  assert 'vs_anchor' not in rows['actor'] and 'departure_share' not in rows['actor']
  md = evaluation_suite.anchor_markdown(list(rows.values()))
  assert '| plan[x] | 4/8 = 0.50 | 0.75, 0.25 | 0.10 | 2 / 4, 0.69 | 2 / 1, 0 / 3 | 3 |' in md


def test_table_per_task_pairs_within_each_task():
  # Task t1: the planner wins 2 episodes on run a; task t2: it loses 3 on run b (3 behind there).
  def tagged(task, recs):
    return [dict(r, task=task) for r in recs]
  records = (tagged('t1', _policy_records('plan[x]', 'a', [1, 1, 0])
                    + _policy_records('actor', 'a', [0, 0, 0])
                    + _policy_records('plan[x]', 'b', [1, 1, 1])
                    + _policy_records('actor', 'b', [1, 1, 1]))
             + tagged('t2', _policy_records('plan[x]', 'a', [1, 1, 1])
                      + _policy_records('actor', 'a', [1, 1, 1])
                      + _policy_records('plan[x]', 'b', [0, 0, 0])
                      + _policy_records('actor', 'b', [1, 1, 1])))
  by_task = evaluation_suite.against_anchor_by_task(records)
  assert list(by_task) == ['t1', 't2']
  t1 = {r['policy']: r for r in by_task['t1']}['plan[x]']
  t2 = {r['policy']: r for r in by_task['t2']}['plan[x]']
  assert (t1['successes'], t1['vs_anchor']['a_only'], t1['vs_anchor']['b_only']) == (5, 2, 0)
  assert (t2['successes'], t2['most_behind']) == (3, 3)
  md = evaluation_suite.by_task_markdown(by_task)
  assert '| t2 | 3/6; 0 / 3, p = 0.25; behind 3 | 6/6 |' in md
  # One task (a single-task checkpoint): no per-task table.
  assert evaluation_suite.against_anchor_by_task(records[:12]) == {}
  assert evaluation_suite.by_task_markdown({}) == ''


def _timed(policy, outcomes, run='A'):
  """[(success, first_success)] per episode -> records of one policy on episodes 0.."""
  return [dict(policy=policy, run=run, split='held_out', eval_seed=0, episode=i, success=s,
               first_success=t if s else None) for i, (s, t) in enumerate(outcomes)]


def test_behind_by_anchor_time_bins_the_anchors_solved_episodes():
  actor = [(1, 50), (1, 60), (1, 80), (1, 120), (1, 130), (0, None), (0, None)]
  plan = [(1, 40), (0, None), (1, 70), (0, None), (0, None), (1, 90), (0, None)]
  # Run B's episode 0 is another episode than run A's: it must not pair with A's actor.
  records = _timed('actor', actor) + _timed('plan', plan) + _timed('plan', [(0, None)], run='B')
  rows = evaluation_suite.behind_by_anchor_time(records, 'actor', edges=(70, 110))
  assert [r['bin'] for r in rows] == ['0-70', '70-110', '110+', 'failed']
  assert [r['episodes'] for r in rows] == [2, 1, 2, 2]
  assert [r.get('lost', r.get('won'))['plan'] for r in rows] == [[1, 2], [0, 1], [2, 2], [1, 2]]
  table = evaluation_suite.behind_markdown(rows)
  assert '| 110+ | 2 | lost 2/2 |' in table and '| failed | 2 | solved 1/2 |' in table
  with pytest.raises(ValueError, match='increasing'):
    evaluation_suite.behind_by_anchor_time(records, 'actor', edges=(110, 70))
  with pytest.raises(ValueError, match="'prior'"):
    evaluation_suite.behind_by_anchor_time(records, 'prior')


def test_action_noise_reaches_the_policy_and_is_its_own_cell(tmp_path, monkeypatch):
  seen = {}
  class Policy:
    def __init__(self, settings, params, mode, seed, chunk, mesh):
      pass
  def run_episodes(policy, eps, *args, **kwargs):
    seen['noise'] = policy.action_noise
    return [dict(success=1)], {}
  monkeypatch.setattr(evaluation_suite, 'BatchAgentPolicy', Policy)
  monkeypatch.setattr(evaluation_suite.evaluation, 'run_episodes', run_episodes)
  monkeypatch.setattr(evaluation_suite.evaluation, 'result', lambda records, info: records)
  monkeypatch.setattr(evaluation_suite, 'episodes', lambda source, split, seed, n: [])
  config = door_open.get_config('smoke')
  evaluation_suite.evaluate_policy(EvalSpec.from_config(config), None, 'actor', 2, seed=0)
  assert seen['noise'] == 0.0
  config.eval.action_noise = 0.05
  evaluation_suite.evaluate_policy(EvalSpec.from_config(config), None, 'actor', 2, seed=0)
  assert seen['noise'] == 0.05
  calls = _stub_evaluations(monkeypatch)
  older = door_open.get_config('smoke')
  del older.eval['action_noise'], older['version']  # Saved before the field: read back at 0, the same cell.
  checkpointing.save_config(older, str(tmp_path / 'old_run'))
  older = checkpointing.load_config(str(tmp_path / 'old_run'))
  for c in (older, door_open.get_config('smoke'), config):
    evaluation_suite.evaluate_checkpoint(EvalSpec.from_config(c), None, str(tmp_path),
                                         **_ONE_CELL)
  assert len(calls) == 2
