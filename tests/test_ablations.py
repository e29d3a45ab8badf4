"""The ablation variants (energy guidance, MPPI, kinds that cannot plan together) and the sweep's
helpers. Each variant training a step and planning: tests/e2e/test_ablation_variants.py."""

import json

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.cli import ablations
from ld_mpc_jax.plan import agent, planner
from ld_mpc_jax.model import models, objective
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.plan.modes import ActSettings


def test_trajectory_dynamics_rejects_actor_prior_candidates(smoke_config):
  config = ablations.with_overrides(smoke_config, {'model.dynamics_type': 'diffusion_traj',
                                                   'critic.latent_rollout': False,
                                                   'plan.num_prior_candidates': 1})
  with pytest.raises(ValueError, match='num_prior_candidates'):
    planner.make_plan(config)


def test_energy_guidance_raises_the_guided_return(smoke_config):
  """Same key and noise: guided proposals score higher under the guidance rollout's J."""
  guided_cfg = ablations.with_overrides(smoke_config, {'plan.guidance_scale': 1.0,
                                                       'plan.num_candidates': 16})
  plain_cfg = ablations.with_overrides(guided_cfg, {'plan.guidance_scale': 0.0})
  params = models.init_params(guided_cfg, jax.random.key(3))
  nets = models.build_networks(ModelSettings.from_config(guided_cfg))
  z, key = models.encode(params, jnp.linspace(-1, 1, 39)), jax.random.key(4)
  # Jitted: op by op, the guided sampler's gradient compiles many small programs.
  propose = lambda cfg: jax.jit(planner.make_propose(
      ModelSettings.from_config(cfg), PlanSettings.from_config(cfg), nets), static_argnums=3)
  guided = propose(guided_cfg)(params, z, key, 16)
  plain = propose(plain_cfg)(params, z, key, 16)
  assert np.all(np.abs(np.asarray(guided)) <= 1.0)
  assert float(jnp.abs(guided - plain).max()) > 1e-3
  score_cfg = ablations.with_overrides(plain_cfg, {'plan.dynamics_steps': 1,
                                                   'plan.dynamics_eta': 0.0})
  m, p = ModelSettings.from_config(score_cfg), PlanSettings.from_config(score_cfg)
  rollout = planner.make_rollout(m, p, nets)
  score = objective.make_score(m, nets, p.pessimism, p.progress_weight)
  j = jax.jit(lambda acts: score(params, rollout(params, z, acts, jax.random.key(5))[1],
                                 acts).mean())
  assert float(j(guided)) > float(j(plain))


def test_guidance_needs_a_sequence_proposal(smoke_config):
  config = ablations.with_overrides(smoke_config, {'plan.guidance_scale': 1.0,
                                                   'model.proposal_type': 'mlp'})
  with pytest.raises(ValueError, match='guidance_scale'):
    planner.make_plan(config)


def test_mppi_mode_acts_within_bounds_and_is_deterministic(smoke_config, smoke_params):
  config = ablations.with_overrides(smoke_config, {'mppi.num_samples': 8, 'mppi.num_elites': 2,
                                                   'mppi.num_prior': 2, 'mppi.iterations': 2})
  act = agent.make_act(ActSettings.from_config(config), 'mppi')
  obs = jnp.linspace(-1, 1, 39)
  a1, mean, _ = act(smoke_params, obs, jax.random.key(0), 0, None)
  a2, _, _ = act(smoke_params, obs, jax.random.key(0), 0, None)
  chex.assert_shape(mean, (config.horizon, config.action_dim))
  np.testing.assert_array_equal(a1, a2)
  assert np.all(np.abs(np.asarray(a1)) <= 1.0)


def test_seed_interval_matches_hand_computed_t_interval():
  lo, hi = ablations.seed_interval([0.5, 0.6, 0.7])
  half = 4.303 * 0.1 / np.sqrt(3)  # t(0.975, 2 degrees of freedom) = 4.303 in tables.
  np.testing.assert_allclose([lo, hi], [0.6 - half, 0.6 + half], rtol=1e-4)
  assert ablations.seed_interval([0.9, 1.0, 1.0])[1] == 1.0  # Clipped.
  assert ablations.seed_interval([0.4]) == [0.4, 0.4]


def test_row_aggregates_mixed_seeds_and_expert():
  r = lambda s: {'success_rate': s, 'success_ci95': [s - 0.1, s], 'mean_return': 100 * s,
                 'decisions_per_s': 10.0, 'num_params': 7}
  out = ablations.row('x', {('mixed', 0): r(0.2), ('mixed', 1): r(0.4), ('expert', 0): r(1.0)})
  assert out['mixed_success_per_seed'] == [0.2, 0.4]
  np.testing.assert_allclose(out['mixed_success_mean'], 0.3)
  np.testing.assert_allclose(out['mixed_return_mean'], 30.0)
  assert out['expert_success'] == 1.0 and out['num_params'] == 7


def test_finished_runs_are_reused_not_retrained(tmp_path, smoke_config):
  workdir = tmp_path / 'mixed' / 'ldmpc' / 'seed0'
  workdir.mkdir(parents=True)
  (workdir / 'report.json').write_text(json.dumps({'success_rate': 0.5}))
  assert ablations.train_variant(smoke_config, 'ldmpc', 'mixed', 0, str(tmp_path), 1) == {
      'success_rate': 0.5}
  cached = workdir / 'eval_mppi.json'
  cached.write_text(json.dumps({'success_rate': 0.25}))
  assert ablations.evaluate_on(str(tmp_path), 'ldmpc', 'mixed', 0, 'eval_mppi', {}, 'mppi',
                               1)['success_rate'] == 0.25


def _episodes(seed_count=50, eval_seed=0):
  return [dict(split='held_out', eval_seed=eval_seed, episode=i, reset_seed=1000 + i,
               goal_id=f'g{i}') for i in range(seed_count)]


def _write_planner(root, seed, successes):
  workdir = root / 'mixed' / 'ldmpc' / f'seed{seed}'
  workdir.mkdir(parents=True)
  rows = [dict(run=1, policy=p, **e, success=s) for p in ('plan', 'actor')
          for e, s in zip(_episodes(len(successes)), successes)]
  header = list(rows[0])
  lines = [','.join(header)] + [','.join(str(r[k]) for k in header) for r in rows]
  (workdir / 'episodes.csv').write_text('\n'.join(lines) + '\n')
  return workdir


def test_paired_table_pools_the_seeds_on_the_same_episodes(tmp_path):
  plan = {0: [1, 1, 0, 0], 1: [1, 0, 1, 1]}
  actor = {0: [0, 1, 1, 0], 1: [0, 0, 0, 1]}
  for seed in plan:
    workdir = _write_planner(tmp_path, seed, plan[seed])
    records = [dict(e, success=s) for e, s in zip(_episodes(4), actor[seed])]
    (workdir / 'eval_actor.json').write_text(json.dumps({'records': records}))
  pairs = [('mixed', 0), ('mixed', 1)]
  t = ablations.paired_with(str(tmp_path), 'ldmpc', 'actor', pairs)
  assert (t['n'], t['a_only'], t['b_only']) == (8, 3, 1)
  # Files of a sweep that ran the baseline on other episodes are not paired.
  records = [dict(e, success=1) for e in _episodes(4, eval_seed=1)]
  (tmp_path / 'mixed' / 'ldmpc' / 'seed1' / 'eval_actor.json').write_text(
      json.dumps({'records': records}))
  assert ablations.paired_with(str(tmp_path), 'ldmpc', 'actor', pairs) is None
  md = ablations.paired_md(str(tmp_path), {'ldmpc': {}, 'actor': {}}, pairs,
                           {'ldmpc': 'five', 'actor': 'prior'})
  assert '| prior | - | - | not run on the same episodes |' in md


def test_baselines_run_the_variants_evaluation_seed_not_the_training_seed(
    tmp_path, monkeypatch, smoke_config):
  from ld_mpc_jax.learn import checkpointing
  from ld_mpc_jax.runs import loop as runs
  workdir = tmp_path / 'mixed' / 'ldmpc' / 'seed2'
  workdir.mkdir(parents=True)
  (workdir / 'report.json').write_text(json.dumps({'num_params': 3}))
  smoke_config.eval.seeds = (7,)
  monkeypatch.setattr(checkpointing, 'load_for_evaluation',
                      lambda w, check=None: (smoke_config, {}, 4))
  seen = []
  monkeypatch.setattr(runs, 'run_evaluation', lambda c, p, mode, n, seed, **k: seen.append(
      seed) or {'success_rate': 0.5, 'successes': 1, 'records': []})
  out = ablations.evaluate_on(str(tmp_path), 'ldmpc', 'mixed', 2, 'eval_actor', {}, 'actor', 2)
  assert seen == [7] and out['eval_seed'] == 7 and out['num_params'] == 3
