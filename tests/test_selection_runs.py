"""ld_mpc_jax.analysis.selection_runs (compare_selection's evaluation): which policies and settings one
checkpoint is evaluated with (evaluations stubbed; the tables: test_evaluation_suite.py)."""

from ld_mpc_jax.configs import overrides
from ld_mpc_jax.analysis import selection_runs
from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.eval import multitask_eval


def test_every_variant_and_actor_variant_runs_with_its_own_settings(monkeypatch):
  # Safe selection needs the actor prior's own sequence among the candidates (validate_config).
  config = overrides.with_overrides(door_open.get_config('smoke'), {'plan.num_prior_candidates': 1})
  monkeypatch.setattr(checkpointing, 'load_for_evaluation', lambda workdir, check: (config, 'P', 7))
  seen = []
  def evaluate(spec, params, workdir, step, modes, splits, seeds, episodes, run):
    seen.append((modes[0], spec.act.plan.safe_selection, spec.eval.action_noise))
    return [dict(success=1, episode=i) for i in range(episodes)]
  monkeypatch.setattr(multitask_eval, 'grid', lambda spec, splits: (None, evaluate))
  records = selection_runs.evaluate_run(
      'runs/x', [overrides.parse_variant('safe:plan.safe_selection=True')], ['actor'],
      episodes=2, seed=0, actor_variants=[overrides.parse_variant('noisy:eval.action_noise=0.05')])
  assert seen == [('plan', True, 0.0), ('actor', False, 0.0), ('actor', False, 0.05)]
  assert [r['policy'] for r in records] == ['plan[safe]'] * 2 + ['actor'] * 2 + ['actor[noisy]'] * 2
  assert {r['train_seed'] for r in records} == {config.seed}
  assert config.eval.action_noise == 0.0  # The variants changed copies.
