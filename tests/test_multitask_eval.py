"""ld_mpc_jax.eval.multitask_eval: per-task tables of hand-built records, and every task evaluated as a
single-task agent (evaluations stubbed, no environment runs)."""

import math
import os

import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, mt10
from ld_mpc_jax.eval import evaluation_suite, multitask_eval
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.ops import stats

# Successes of held-out episodes per task (c has twice as many); the actor prior was evaluated
# on two tasks only.
PLAN = {'a': [1, 1, 0, 0], 'b': [1, 1, 1, 1], 'c': [0, 0, 1, 0, 0, 0, 0, 0]}  # 7/16; .5, 1, .125.
ACTOR = {'a': [1, 0, 0, 0], 'b': [0, 0, 0, 0]}  # 1/8.


def _records():
  return [dict(task=task, split='held_out', policy=policy, eval_seed=0, episode=i, success=s)
          for policy, table in (('plan', PLAN), ('actor', ACTOR))
          for task, outcomes in table.items() for i, s in enumerate(outcomes)]


def test_per_task_rates_and_their_average():
  table = multitask_eval.per_task(_records(), ['a', 'b', 'c'])
  plan, actor = table['held_out']['plan'], table['held_out']['actor']
  assert list(table['held_out']) == ['plan', 'actor']
  assert {n: s['successes'] for n, s in plan['tasks'].items()} == {'a': 2, 'b': 4, 'c': 1}
  assert list(actor['tasks']) == ['a', 'b']  # Only the tasks it has records of.
  avg, mean = plan['average'], (0.5 + 1.0 + 0.125) / 3
  assert avg['success_rate'] == pytest.approx(mean)  # The tasks' mean, not the pooled 7/16.
  assert (avg['successes'], avg['episodes']) == (7, 16)
  assert avg['success_ci95'] == stats.wilson_interval(7, 16)  # All episodes pooled.
  assert avg['task_rate_std'] == pytest.approx(math.sqrt(
      ((0.5 - mean) ** 2 + (1.0 - mean) ** 2 + (0.125 - mean) ** 2) / 2))
  assert actor['average']['success_rate'] == pytest.approx(0.125)
  one = multitask_eval.per_task([r for r in _records() if r['task'] == 'a'], ['a', 'b', 'c'])
  assert one['held_out']['plan']['average']['task_rate_std'] is None  # A single task.


def test_markdown_has_a_row_per_task_every_policy_has(tmp_path):
  names = ['a', 'b', 'c']
  table = multitask_eval.per_task(_records(), names)
  lines = multitask_eval.markdown(table, names).splitlines()
  assert '| task | planner | actor prior |' in lines
  lo, hi = stats.wilson_interval(1, 4)
  assert f'| a | 2/4 = 0.50 [{stats.wilson_interval(2, 4)[0]:.2f}, ' \
         f'{stats.wilson_interval(2, 4)[1]:.2f}] | 1/4 = 0.25 [{lo:.2f}, {hi:.2f}] |' in lines
  assert not any(l.startswith('| c |') for l in lines)  # The actor has no records of c.
  lo, hi = stats.wilson_interval(7, 16)
  assert any(l.startswith(f'| **average** | **0.54** [{lo:.2f}, {hi:.2f}] |') for l in lines)
  path = multitask_eval.plot(str(tmp_path / 'plots' / 'tasks.png'), table, names)
  assert os.path.getsize(path) > 0


def _stub_checkpoint(monkeypatch):
  """evaluation_suite.evaluate_checkpoint stubbed: 2 records per (task, mode)."""
  calls = []

  def fake(spec, params, workdir, step, modes, splits, seeds, num_episodes, run=None,
           obs_noise_std=0.0, log=print):
    calls.append((spec.task, spec.multitask or spec.act.model.multitask, params))
    log(f'{modes[0]} done')
    k = len(calls)  # The k-th task: k successes of 2 (capped), k x 10 decisions/s.
    return [dict(split=splits[0], policy=m, eval_seed=seeds[0], episode=i, run=run,
                 success=int(i < k), decisions_per_s=10.0 * k)
            for m in modes for i in range(num_episodes)]

  monkeypatch.setattr(evaluation_suite, 'evaluate_checkpoint', fake)
  return calls


def test_each_task_is_evaluated_as_a_single_task_agent(monkeypatch):
  calls = _stub_checkpoint(monkeypatch)
  config = mt10.get_config('smoke')
  config.tasks, config.train.batch_size = config.tasks[:3], 12  # Equal shares (checked).
  params, lines = {'encoder': {}}, []  # No 'task' entry: tasks.bind returns it unchanged.
  spec = EvalSpec.from_config(config)
  records = multitask_eval.evaluate_tasks(spec, params, None, 0, ('plan',), ('held_out',),
                                          (0,), 2, run=1, log=lines.append)
  names = list(config.tasks)
  assert calls == [(n, False, params) for n in names]
  assert [r['task'] for r in records] == [n for n in names for _ in range(2)]
  assert lines == [f'{n}: plan done' for n in names]
  calls.clear()
  pooled = multitask_eval.evaluate_pooled(spec, params, 'plan', 2, 0)
  assert (pooled['successes'], pooled['episodes']) == (1 + 2 + 2, 6)
  assert pooled['decisions_per_s'] == 20.0  # The median of 10, 20 and 30.


def test_only_the_named_tasks_are_evaluated(monkeypatch):
  calls = _stub_checkpoint(monkeypatch)
  config = mt10.get_config('smoke')
  config.tasks, config.train.batch_size = config.tasks[:3], 12  # Equal shares (checked).
  params, spec = {'encoder': {}}, EvalSpec.from_config(config)
  records = multitask_eval.evaluate_tasks(spec, params, None, 0, ('plan',), ('held_out',),
                                          (0,), 2, log=lambda line: None, only=(config.tasks[2],))
  assert [c[0] for c in calls] == [config.tasks[2]]
  assert {r['task'] for r in records} == {config.tasks[2]}
  with pytest.raises(ValueError, match="task 'nope-v3' is not one of"):
    multitask_eval.evaluate_tasks(spec, params, None, 0, ('plan',), ('held_out',), (0,), 2,
                                  only=('nope-v3',))


def test_grid_picks_the_evaluation_for_the_config(monkeypatch):
  splits, fn = multitask_eval.grid(EvalSpec.from_config(mt10.get_config('smoke')),
                                   ('held_out', 'train'))
  assert splits == ('held_out', 'train') and fn is multitask_eval.evaluate_tasks
  monkeypatch.setattr(evaluation_suite, 'dataset_goals', lambda c: (np.zeros((1, 6)), None))
  splits, fn = multitask_eval.grid(EvalSpec.from_config(door_open.get_config('smoke')),
                                   ('held_out', 'train'))
  assert splits == ('held_out',) and fn is evaluation_suite.evaluate_checkpoint
