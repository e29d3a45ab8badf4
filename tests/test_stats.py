"""ld_mpc_jax.ops.stats: Wilson intervals, exact McNemar, pooling records."""

import numpy as np
import pytest

from ld_mpc_jax.ops import stats


def test_wilson_interval_hand_values():
  lo, hi = stats.wilson_interval(5, 10)
  assert lo == pytest.approx(0.2366, abs=1e-4) and hi == pytest.approx(0.7634, abs=1e-4)
  assert stats.wilson_interval(0, 50)[0] == pytest.approx(0.0, abs=1e-12)
  assert stats.wilson_interval(0, 50)[1] == pytest.approx(0.0713, abs=1e-4)
  assert stats.wilson_interval(50, 50)[1] == pytest.approx(1.0)


def test_mcnemar_exact_matches_hand_computed_binomial_tails():
  # 8 episodes only a succeeded, 2 only b, 5 both, 5 neither: two-sided binomial p of 2 of 10
  # under 1/2: 2 * (C(10,0) + C(10,1) + C(10,2)) / 2^10 = 2 * 56 / 1024.
  a = [1] * 8 + [0] * 2 + [1] * 5 + [0] * 5
  b = [0] * 8 + [1] * 2 + [1] * 5 + [0] * 5
  t = stats.mcnemar_exact(a, b)
  assert (t['n'], t['a_only'], t['b_only']) == (20, 8, 2)
  assert t['p_value'] == pytest.approx(112 / 1024)
  # Symmetric, and 1 with no discordant pairs; 6 to 0: 2 / 2^6.
  assert stats.mcnemar_exact(b, a)['p_value'] == pytest.approx(112 / 1024)
  assert stats.mcnemar_exact([1, 0], [1, 0])['p_value'] == 1.0
  assert stats.mcnemar_exact([1] * 6, [0] * 6)['p_value'] == pytest.approx(2 / 64)
  with pytest.raises(ValueError, match='same episodes'):
    stats.mcnemar_exact([1, 0], [1])


def test_pooled_records_give_the_summary_rate_and_pair_on_episode_keys():
  rng = np.random.default_rng(0)
  recs = [dict(run=r, split='held_out', eval_seed=s, episode=i, success=int(rng.random() < 0.7),
               **{'return': float(i)}, length=10, env_steps=20)
          for r in range(3) for s in range(2) for i in range(50)]
  summary = stats.summarize(recs)
  assert summary['episodes'] == 300
  assert summary['successes'] == sum(r['success'] for r in recs)
  assert summary['success_rate'] == pytest.approx(np.mean([r['success'] for r in recs]))
  # Pooling per-run summaries by counts gives the same rate.
  parts = [stats.summarize(stats.select(recs, run=r)) for r in range(3)]
  assert sum(p['successes'] for p in parts) / sum(p['episodes'] for p in parts) == (
      pytest.approx(summary['success_rate']))
  assert stats.spread(recs, 'run')['rates']['0'] == pytest.approx(parts[0]['success_rate'])
  # Pairing matches episodes by key whatever the order.
  flipped = [{**r, 'success': 1 - r['success']} for r in reversed(recs)]
  t = stats.paired(recs, flipped)
  assert t['n'] == 300 and t['a_only'] + t['b_only'] == 300
  with pytest.raises(ValueError, match='share no episode'):
    stats.paired(recs, [{**recs[0], 'run': 99}])
