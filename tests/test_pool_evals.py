"""experiments.pool_evals: pooling evaluation results over seeds."""

import json

import pytest

from experiments import pool_evals


def _result(rates: dict, episodes: int = 50) -> dict:
  return {'episodes': episodes, 'modes': {m: {'success_rate': r} for m, r in rates.items()}}


def test_pool_counts_successes_over_files_and_gives_a_wilson_interval():
  pooled = pool_evals.pool([_result({'plan': 1.0, 'actor': 0.92}),
                            _result({'plan': 0.98}), _result({'plan': 0.5}, episodes=10)])
  plan = pooled['plan']
  assert (plan['successes'], plan['episodes']) == (50 + 49 + 5, 110)
  assert plan['success_rate'] == pytest.approx(104 / 110)
  assert plan['rates'] == [1.0, 0.98, 0.5]
  lo, hi = plan['success_ci95']
  assert 0.88 < lo < 104 / 110 < hi < 0.98
  assert pooled['actor']['successes'] == 46 and pooled['actor']['episodes'] == 50


def test_main_prints_one_line_per_mode(tmp_path, capsys):
  paths = []
  for i, rate in enumerate((1.0, 0.98)):
    path = tmp_path / f'seed{i}.json'
    path.write_text(json.dumps(_result({'plan': rate})))
    paths.append(str(path))
  pool_evals.main(paths)
  assert capsys.readouterr().out.strip() == (
      'plan: 99/100 = 0.990 [0.95, 1.00] (per file: 1.00, 0.98)')
