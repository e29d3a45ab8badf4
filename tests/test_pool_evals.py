"""experiments.report: pooling evaluation records over files."""

import os
import gzip
import json

import pytest

from ld_mpc_jax.cli import pool as pool_evals

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _result(outcomes: dict) -> dict:
  """{mode: [0/1 per episode]} -> an evaluate JSON with records (held-out goals, seed 0)."""
  return {'records': [dict(policy=m, split='held_out', eval_seed=0, episode=i, success=s,
                           **{'return': 1.0})
                      for m, out in outcomes.items() for i, s in enumerate(out)]}


def test_pool_counts_records_over_files_and_pairs_within_a_file():
  a = _result({'plan': [1] * 10, 'actor': [1] * 6 + [0] * 4})
  b = _result({'plan': [1] * 9 + [0], 'actor': [1] * 5 + [0] * 5})
  s = pool_evals.pool([a, b], ['a', 'b'])['held_out']
  plan = s['policies']['plan']
  assert (plan['successes'], plan['episodes']) == (19, 20)
  assert plan['success_rate'] == pytest.approx(0.95)
  assert plan['per_run']['rates'] == {'a': 1.0, 'b': 0.9}
  t = s['paired']['plan vs actor']
  # Episodes pair within a file only: plan-only successes 4 + 4 = 8, actor-only 0.
  assert (t['n'], t['a_only'], t['b_only']) == (20, 8, 0)
  assert t['p_value'] == pytest.approx(2 / 2 ** 8)


def test_pool_keeps_the_runs_of_one_file_apart():
  # One compare_selection JSON over two checkpoints: episode i of run A is not episode i of B.
  a = _result({'plan': [1, 1, 0, 0], 'actor': [0, 0, 1, 1]})
  b = _result({'plan': [0, 0, 1, 1], 'actor': [1, 1, 0, 0]})
  both = {'records': [{**r, 'run': run} for run, res in (('A', a), ('B', b))
                      for r in res['records']]}
  s = pool_evals.pool([both], ['sel.json'])['held_out']
  assert s['policies']['plan']['per_run']['rates'] == {'sel.json:A': 0.5, 'sel.json:B': 0.5}
  t = s['paired']['plan vs actor']
  # Paired within each run: 2 + 2 plan-only and 2 + 2 actor-only; pairing across runs would
  # have given 0 discordant episodes.
  assert (t['n'], t['a_only'], t['b_only']) == (8, 4, 4)


def test_policies_from_different_files_pool_without_a_paired_test():
  # 'safe' was evaluated in one file, 'argmax' in another: each pools, but they share no
  # episode, so only the pairs within a file are tested (no error).
  a = _result({'argmax': [1, 1, 0, 0], 'actor': [1, 0, 0, 0]})
  b = _result({'safe': [1, 1, 1, 0], 'actor': [1, 0, 0, 0]})
  s = pool_evals.pool([a, b], ['a', 'b'])['held_out']
  assert s['policies']['actor']['successes'] == 2
  assert set(s['paired']) == {'argmax vs actor', 'actor vs safe'}  # In order of appearance.
  t = s['paired']['actor vs safe']
  assert (t['n'], t['a_only'], t['b_only']) == (4, 0, 2)


def test_main_prints_per_task_table_pooled_over_files(tmp_path, capsys):
  paths = []
  for name, outcomes in (('a', [1, 1, 0, 0]), ('b', [1, 0, 0, 0])):
    res = _result({'plan': outcomes})
    for r in res['records']:  # Two tasks, two episodes each.
      r['task'], r['episode'] = ('reach-v3', 'push-v3')[r['episode'] // 2], r['episode'] % 2
    paths.append(tmp_path / f'{name}.json.gz')  # Compressed records read as they are.
    with gzip.open(paths[-1], 'wt') as f:
      json.dump(res, f)
  pool_evals.run([str(p) for p in paths])
  out = capsys.readouterr().out
  assert '| reach-v3 | 3/4 = 0.75' in out and '| push-v3 | 0/4 = 0.00' in out
  assert '**average** | **0.38**' in out


def test_main_pools_multi_and_single_task_files_together(tmp_path, capsys):
  """Several settings in one test: the per-task table has the multi-task records alone, the
  pooled table every record (3 of 4 here, where the per-task table says 1 of 2)."""
  multi = _result({'plan': [1, 0]})
  for r in multi['records']:
    r['task'] = 'reach-v3'
  paths = [tmp_path / 'multi.json', tmp_path / 'single.json']
  paths[0].write_text(json.dumps(multi))
  paths[1].write_text(json.dumps(_result({'plan': [1, 1]})))
  pool_evals.run([str(p) for p in paths])
  out = capsys.readouterr().out
  assert '| reach-v3 | 1/2 = 0.50' in out
  assert 'the pooled table below has all 4 records' in out
  assert '3/4 = 0.75' in out


def test_main_rejects_files_without_records(tmp_path, capsys):
  path = tmp_path / 'old.json'
  path.write_text(json.dumps({'modes': {'plan': {'success_rate': 1.0}}}))
  with pytest.raises(SystemExit) as err:
    pool_evals.run([str(path)])
  assert err.value.code == 2 and 'no per-episode records' in capsys.readouterr().err


def test_compare_sweeps_pairs_the_same_episodes():
  from ld_mpc_jax.cli import compare_sweeps
  rec = lambda run, ep, policy, success: dict(run=run, split='held_out', eval_seed=0,
                                              episode=ep, policy=policy, success=success)
  a = {'records': [rec(0, 0, 'plan', 1), rec(0, 1, 'plan', 1), rec(1, 0, 'plan', 1),
                   rec(2, 5, 'plan', 1)]}
  b = {'records': [rec(0, 0, 'plan', 0), rec(0, 1, 'plan', 1), rec(1, 0, 'plan', 0),
                   rec(1, 0, 'actor', 1)]}
  (row,) = compare_sweeps.paired_rows(a, b, ['plan', 'actor'], 'held_out')
  assert (row['episodes'], row['a'], row['b'], row['a_only'], row['b_only']) == (3, 3, 1, 2, 0)
  assert row['seeds'] == [0, 1] and row['p_value'] == 0.5


def test_compare_sweeps_side_of_several_files_pools_their_records(tmp_path):
  from ld_mpc_jax.cli import compare_sweeps
  rec = lambda run, success: dict(run=run, split='held_out', eval_seed=0, episode=0,
                                  policy='plan', success=success)
  paths = []
  for run in (0, 1):
    paths.append(tmp_path / f'seed{run}.json')
    paths[-1].write_text(json.dumps({'records': [rec(run, run)]}))
  side = compare_sweeps.read_side(','.join(map(str, paths)))
  a = {'records': [rec(0, 1), rec(1, 1)]}
  (row,) = compare_sweeps.paired_rows(a, side, ['plan'], 'held_out')
  assert (row['episodes'], row['a'], row['b'], row['seeds']) == (2, 2, 1, [0, 1])


def test_compare_sweeps_reads_episodes_csv_and_refuses_other_goals(tmp_path, capsys):
  from ld_mpc_jax.cli import compare_sweeps
  from ld_mpc_jax.eval import run_files
  rec = lambda ep, success, goal: dict(run=1, policy='plan', split='held_out', eval_seed=0,
                                       episode=ep, reset_seed=7, goal_id=goal, success=success,
                                       first_success=0, env_steps=0, length=0, **{'return': 0.0})
  path = str(tmp_path / 'episodes.csv')
  run_files.write_records(path, [rec(0, 1, 'g0'), rec(1, 0, 'g1')])
  side = compare_sweeps.read_side(path)
  a = {'records': [rec(0, 0, 'g0'), rec(1, 0, 'g1')]}
  (row,) = compare_sweeps.paired_rows(a, side, ['plan'], 'held_out')
  assert (row['episodes'], row['a'], row['b'], row['a_only'], row['b_only']) == (2, 0, 1, 0, 1)
  other = {'records': [rec(0, 0, 'g0'), rec(1, 0, 'gX')]}
  with pytest.raises(SystemExit) as err:
    compare_sweeps.paired_rows(other, side, ['plan'], 'held_out')
  assert err.value.code == 2 and 'goal gX in A but g1 in B' in capsys.readouterr().err


def test_main_reads_a_runs_episodes_csv(tmp_path, capsys):
  path = tmp_path / 'episodes.csv'
  rows = ['run,policy,split,eval_seed,episode,reset_seed,goal_id,success,first_success,return,'
          'length,env_steps']
  for i, (p, a) in enumerate([(1, 0), (1, 0), (1, 1), (0, 0)]):
    rows.append(f'0,plan,held_out,0,{i},{i},g{i},{p},,{10.0 * p},50,100')
    rows.append(f'0,actor,held_out,0,{i},{i},g{i},{a},,2.5,50,100')
  path.write_text('\n'.join(rows) + '\n')
  pool_evals.run([str(path)])
  out = capsys.readouterr().out
  assert '| held_out | planner | 3/4 = 0.75 |' in out and '| 7.5 | not recorded |' in out
  assert '| held_out | planner vs actor prior | 4 | 2 | 0 | 0.5 |' in out


def test_report_prints_its_usage_for_help_and_refuses_unknown_flags():
  import subprocess, sys  # pylint: disable=g-import-not-at-top,multiple-imports
  done = subprocess.run([sys.executable, '-m', 'experiments.report', '--help'], capture_output=True,
                        text=True, cwd=ROOT)
  assert 'python -m experiments.report curves' in done.stdout  # absl's --help exits 1.
  assert '--noise_plot' in done.stdout  # The mode's own flags.
  done = subprocess.run([sys.executable, '-m', 'experiments.report', 'a.json', '--policies=plan'],
                        capture_output=True, text=True, cwd=ROOT)
  assert done.returncode == 2 and done.stderr.strip().startswith('error:')
  assert len(done.stderr.strip().splitlines()) == 1 and 'policies' in done.stderr


def test_compare_sweeps_pairs_compare_selection_files_by_training_seed(tmp_path, capsys):
  from ld_mpc_jax.cli import compare_sweeps
  sides = []
  for name, seed_of, success in (('a', {'x': 3, 'y': 4}, 1), ('b', {'u': 4, 'v': 3}, 0)):
    records = []
    for run, seed in seed_of.items():
      workdir = tmp_path / run
      workdir.mkdir()
      (workdir / 'config.json').write_text(json.dumps({'seed': seed}))
      records.append(dict(run=str(workdir), split='held_out', eval_seed=0, episode=0,
                          policy='plan[argmax]', success=success if seed == 3 else 1))
    (tmp_path / f'{name}.json').write_text(json.dumps({'records': records}))
    sides.append(compare_sweeps.read_side(str(tmp_path / f'{name}.json')))
  (row,) = compare_sweeps.paired_rows(*sides, ['plan[argmax]'], 'held_out')
  # Seed 3 (x against v) differs, seed 4 (y against u) does not.
  assert (row['episodes'], row['a'], row['b'], row['a_only'], row['seeds']) == (2, 2, 1, 1, [3, 4])
  (tmp_path / 'x' / 'config.json').unlink()
  with pytest.raises(SystemExit) as err:
    compare_sweeps.read_side(str(tmp_path / 'a.json'))
  assert err.value.code == 2 and 'training seed cannot be read' in capsys.readouterr().err


def test_compare_sweeps_pairs_two_differently_named_policies():
  from ld_mpc_jax.cli import compare_sweeps
  rec = lambda policy, ep, success: dict(run=0, split='held_out', eval_seed=0, episode=ep,
                                         policy=policy, success=success)
  a = {'records': [rec('plan[k64]', 0, 1), rec('plan[k64]', 1, 0)]}
  b = {'records': [rec('plan[k4]', 0, 0), rec('plan[k4]', 1, 0), rec('plan[k64]', 0, 1)]}
  (row,) = compare_sweeps.paired_rows(a, b, ['plan[k64]=plan[k4]'], 'held_out')
  assert (row['episodes'], row['a'], row['b'], row['a_only'], row['b_only']) == (2, 1, 0, 1, 0)
  assert row['policy'] == 'plan[k64]=plan[k4]'


def test_compare_sweeps_takes_the_recorded_training_seed_without_the_workdir(tmp_path):
  from ld_mpc_jax.cli import compare_sweeps
  rec = lambda run, seed, success: dict(run=run, train_seed=seed, split='held_out', eval_seed=0,
                                        episode=0, policy='plan[argmax]', success=success)
  for name, records in (('a', [rec('/gone/x', 5, 1)]), ('b', [rec('/gone/y', 5, 0)])):
    (tmp_path / f'{name}.json').write_text(json.dumps({'records': records}))
  sides = [compare_sweeps.read_side(str(tmp_path / f'{n}.json')) for n in 'ab']
  (row,) = compare_sweeps.paired_rows(*sides, ['plan[argmax]'], 'held_out')
  assert (row['episodes'], row['a_only'], row['seeds']) == (1, 1, [5])


def test_where_behind_prints_the_bins_and_fails_in_one_line(tmp_path):
  import os
  import subprocess
  import sys
  rec = lambda p, i, s, t: dict(policy=p, run=0, split='held_out', eval_seed=0, episode=i,
                                success=s, first_success=t)
  path = tmp_path / 'sel.json'
  path.write_text(json.dumps({'records': [rec('actor', 0, 1, 30), rec('actor', 1, 1, 150),
                                          rec('plan', 0, 1, 20), rec('plan', 1, 0, None)]}))
  repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  run = lambda *a: subprocess.run([sys.executable, '-m', 'experiments.report', 'behind', *a],
                                  capture_output=True, text=True, timeout=60, cwd=repo)
  done = run(str(path))
  assert done.returncode == 0, done.stderr[-2000:]
  assert '| 0-70 | 1 | lost 0/1 |' in done.stdout and '| 110+ | 1 | lost 1/1 |' in done.stdout
  bad = run(str(path), '--anchor=prior')
  lines = [l for l in bad.stderr.splitlines() if l.strip()]
  assert bad.returncode == 2 and lines == ["error: no records of the anchor policy 'prior'"], lines


def test_joined_files_are_one_run_whose_policies_pair(tmp_path, capsys):
  # The same checkpoint evaluated twice: 'safe' and the actor prior first, 'more' later; the
  # actor prior is in both and counts once.
  first = _result({'safe': [1, 1, 0, 0], 'actor': [1, 0, 0, 1]})
  later = _result({'more': [1, 1, 1, 0], 'actor': [1, 0, 0, 1]})
  paths = []
  for name, res in (('first', first), ('later', later)):
    paths.append(str(tmp_path / f'{name}.json'))
    with open(paths[-1], 'w') as f:
      json.dump(res, f)
  records = pool_evals.read_joined('+'.join(paths))
  assert len(records) == 12
  s = pool_evals.pool([{'records': records}], ['joined'])['held_out']
  assert s['policies']['actor']['successes'] == 2
  t = s['paired']['safe vs more']
  assert (t['n'], t['a_only'], t['b_only']) == (4, 0, 1)
  later['records'][-1]['success'] = 0  # The actor prior's last episode now differs.
  with open(paths[1], 'w') as f:
    json.dump(later, f)
  with pytest.raises(SystemExit):
    pool_evals.read_joined('+'.join(paths))
  assert 'not the same checkpoints' in capsys.readouterr().err


def test_a_run_less_json_joined_with_a_run_counts_a_shared_policy_once(tmp_path):
  # An evaluation JSON of one checkpoint (records without `run`) joined with that run's records
  # (run = the training seed): the actor prior in both is one set of episodes, not two.
  with_run = _result({'plan': [1, 1, 0, 1], 'actor': [1, 0, 0, 1]})
  for r in with_run['records']:
    r['run'] = 2
  run_less = _result({'bc': [0, 0, 1, 0], 'actor': [1, 0, 0, 1]})
  paths = [str(tmp_path / 'run.json'), str(tmp_path / 'bc.json')]
  for path, res in zip(paths, (with_run, run_less)):
    with open(path, 'w') as f:
      json.dump(res, f)
  records = pool_evals.read_joined('+'.join(paths))
  assert len(records) == 12 and {r['run'] for r in records} == {2}
  s = pool_evals.pool([{'records': records}], ['joined'])['held_out']
  assert s['policies']['actor']['successes'] == 2
  t = s['paired']['plan vs bc']
  assert (t['n'], t['a_only'], t['b_only']) == (4, 3, 1)


def test_an_old_bc_file_with_outcomes_only_pairs_as_bc(tmp_path):
  # `evaluate bc` without --run wrote `records: null` and per-episode `outcomes` (no policy).
  run = _result({'plan': [1, 1, 0, 1]})
  for r in run['records']:
    r['run'] = 0
  old = dict(records=None, outcomes=[
      {k: v for k, v in r.items() if k not in ('policy', 'run')} | dict(success=ok)
      for r, ok in zip(run['records'], [0, 1, 1, 0])])
  paths = [str(tmp_path / 'run.json'), str(tmp_path / 'bc.json')]
  for path, res in zip(paths, (run, old)):
    with open(path, 'w') as f:
      json.dump(res, f)
  assert [r['success'] for r in pool_evals.read_records(paths[1])] == [0, 1, 1, 0]
  t = pool_evals.pool([{'records': pool_evals.read_joined('+'.join(paths))}],
                      ['joined'])['held_out']['paired']['plan vs bc']
  assert (t['n'], t['a_only'], t['b_only']) == (4, 2, 1)


def test_noise_sweeps_pool_with_bc_protocol_records_as_std_zero(tmp_path, capsys):
  """pool_evals pools noise sweeps over files; a BC file whose sweep lacks std 0 counts its
  protocol records there; the policies pair on the episodes of each joined file."""
  import json
  from ld_mpc_jax.cli import pool as pool_evals
  rec = lambda policy, ep, ok, std=None: dict(
      policy=policy, split='held_out', eval_seed=0, episode=ep, run=0, success=ok,
      **({} if std is None else {'obs_noise': std}))
  plan = [rec('plan', i, 1, s) for s in (0.0, 0.05) for i in range(4)]
  (tmp_path / 'ev.json').write_text(json.dumps(dict(
      records=[rec('plan', i, 1) for i in range(4)], noise_sweep=dict(records=plan))))
  bc = dict(records=[rec('bc', i, int(i < 3)) for i in range(4)],
            noise_sweep=dict(records=[rec('bc', i, int(i < 1), 0.05) for i in range(4)]))
  (tmp_path / 'bc.json').write_text(json.dumps(bc))
  pool_evals.run([f'{tmp_path}/ev.json+{tmp_path}/bc.json'])
  out = capsys.readouterr().out
  assert '| 0 | bc | 3/4 = 0.75 |' in out and '| 0.05 | bc | 1/4 = 0.25 |' in out
  assert '| 0.05 | bc | 1/4 = 0.25 | [0.05, 0.70] | 0.33 | 3 / 0, p = 0.25 |' in out


def test_a_tagged_file_pairs_the_same_policy_under_other_settings(tmp_path, capsys):
  """PATH#TAG: the file's policies become POLICY#TAG, joined to another file of the same run
  they pair with its policies episode by episode."""
  import json
  from ld_mpc_jax.cli import pool as pool_evals
  rec = lambda ep, ok: dict(policy='plan', split='held_out', eval_seed=0, episode=ep, run=0,
                            success=ok)
  (tmp_path / 'a.json').write_text(json.dumps(dict(records=[rec(i, 1) for i in range(4)])))
  (tmp_path / 'b.json').write_text(json.dumps(dict(records=[rec(i, int(i > 0)) for i in range(4)])))
  pool_evals.run([f'{tmp_path}/a.json+{tmp_path}/b.json#f'])
  out = capsys.readouterr().out
  assert '| plan#f | 3/4 = 0.75 |' in out and '| held_out | planner vs plan#f | 4 | 1 | 0 |' in out


def test_an_evaluation_json_without_runs_joins_its_checkpoints_episodes_csv(tmp_path, capsys):
  # experiments.train ablations writes the baselines' records without `run`; the variant's own
  # evaluation is the run's episodes.csv (its run: the training seed): joined, they pair.
  path = tmp_path / 'episodes.csv'
  rows = ['run,policy,split,eval_seed,episode,reset_seed,goal_id,success,first_success,return,'
          'length,env_steps']
  rows += [f'1,plan,held_out,0,{i},{i},g{i},{p},,1.0,50,100' for i, p in enumerate([1, 0, 0, 1])]
  path.write_text('\n'.join(rows) + '\n')
  actor = {'records': [dict(policy='actor', split='held_out', eval_seed=0, episode=i, success=a,
                            **{'return': 1.0}) for i, a in enumerate([1, 1, 1, 1])]}
  (tmp_path / 'eval_actor.json').write_text(json.dumps(actor))
  pool_evals.run([f'{path}+{tmp_path}/eval_actor.json'])
  out = capsys.readouterr().out
  assert '| held_out | actor prior | 4/4 = 1.00 |' in out
  assert '| held_out | planner vs actor prior | 4 | 0 | 2 | 0.5 |' in out
