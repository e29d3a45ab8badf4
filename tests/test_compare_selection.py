"""experiments.compare_selection: variant parsing and the table against the actor prior."""

import pytest

from experiments import compare_selection


def test_parse_variant():
  name, items = compare_selection.parse_variant(
      'safe1:plan.safe_selection=True, plan.safe_margin=1.0')
  assert name == 'safe1'
  assert items == {'plan.safe_selection': 'True', 'plan.safe_margin': '1.0'}
  assert compare_selection.parse_variant('argmax:') == ('argmax', {})
  for bad in ('noname', ':plan.x=1', 'a:plan.x'):
    with pytest.raises(ValueError):
      compare_selection.parse_variant(bad)


def _records(policy, run, successes, departures=None):
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
  records = (_records('plan[x]', 'a', [1, 1, 0, 1], departures=[2, 0, 5, 0])
             + _records('actor', 'a', [0, 0, 1, 1])
             + _records('plan[x]', 'b', [0, 0, 0, 1], departures=[0, 0, 0, 1])
             + _records('actor', 'b', [1, 1, 1, 1]))
  rows = {r['policy']: r for r in compare_selection.table(records)}
  plan = rows['plan[x]']
  assert (plan['successes'], plan['episodes']) == (4, 8)
  assert plan['per_run'] == [0.75, 0.25]
  assert plan['departure_share'] == pytest.approx(8 / 80)
  assert (plan['vs_anchor']['a_only'], plan['vs_anchor']['b_only']) == (2, 4)
  assert [(m['a_only'], m['b_only']) for m in plan['vs_anchor_per_run']] == [(2, 1), (0, 3)]
  assert plan['most_behind'] == 3
  assert 'vs_anchor' not in rows['actor'] and 'departure_share' not in rows['actor']
  md = compare_selection.markdown(list(rows.values()))
  assert '| plan[x] | 4/8 = 0.50 | 0.75, 0.25 | 0.10 | 2 / 4, 0.69 | 2 / 1, 0 / 3 | 3 |' in md
