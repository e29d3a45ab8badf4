"""ld_mpc_jax.analysis.diagnostics: held-out windows and their returns, departures from the actor prior,
success per K paired with the largest K, and the report's table."""

import dataclasses

import jax
import numpy as np
import pytest
from scipy import stats as sps

from ld_mpc_jax.analysis import diagnostics
from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings


def test_diagnose_windows_and_returns(monkeypatch, smoke_config, smoke_params):
  from ld_mpc_jax import data
  from ld_mpc_jax.model import models, objective
  length, gamma = 120, smoke_config.gamma

  class OneEpisode:
    num_episodes = 1

    def episode(self, e):
      rng = np.random.default_rng(e)
      return dict(obs=rng.normal(size=(length + 1, 39)), action=rng.uniform(-1, 1, (length, 4)),
                  reward=np.ones(length), success=np.zeros(length, bool))

  monkeypatch.setattr(data, 'get_or_collect', lambda *a, **k: OneEpisode())
  spec = EvalSpec.from_config(smoke_config)
  obs, actions, returns = diagnostics.held_out_windows(spec, 1, stride=5)
  h, starts = smoke_config.horizon, (0, 5, 10, 15)  # Those < 120 - 100.
  assert obs.shape == (4, h + 1, 39) and actions.shape == (4, h, 4)
  ep = OneEpisode().episode(0)
  np.testing.assert_array_equal(obs[2], ep['obs'][10:10 + h + 1])
  np.testing.assert_array_equal(actions[3], ep['action'][15:15 + h])
  np.testing.assert_allclose(returns, [(1 - gamma ** (length - t)) / (1 - gamma) for t in starts])
  corr = diagnostics.objective_correlation(spec.act, smoke_params, obs, actions, returns)
  # J of the encoder's latents of the windows, ranked against the returns here.
  nets = models.build_networks(ModelSettings.from_config(smoke_config))
  score = objective.make_score(ModelSettings.from_config(smoke_config), nets,
                               smoke_config.plan.pessimism, smoke_config.plan.progress_weight)
  j = score(smoke_params, models.encode(smoke_params, obs), actions)
  assert corr['windows'] == 4
  assert corr['spearman_encoder'] == pytest.approx(sps.spearmanr(j, returns).statistic, abs=1e-6)
  assert np.isfinite(corr['spearman_model'])


def test_departures_from_hand_built_records():
  records = [dict(length=10, success=1, departures=0), dict(length=20, success=0, departures=5),
             dict(length=30, success=1, departures=1), dict(length=40, success=0)]  # None: 0.
  out = diagnostics.departures(records)
  assert out['departure_share'] == pytest.approx(6 / 100)
  assert out['success_with_departures'] == [1, 2]
  assert out['success_without_departures'] == [1, 2]
  assert diagnostics.departures([])['departure_share'] == 0.0


def test_success_by_k_pairs_each_k_with_the_largest(monkeypatch, smoke_config):
  """evaluate_policy stubbed: episode i succeeds when i < K; the planner departed from the actor
  prior once in every episode with K > 1."""
  smoke_config.plan.num_candidates, smoke_config.plan.num_prior_candidates = 8, 2
  seen = []

  def fake(spec, params, mode, episodes, seed, split):
    k = spec.act.plan.num_candidates
    seen.append((k, spec.act.plan.num_prior_candidates, mode, split))
    records = [dict(episode=i, success=int(i < k), length=10, departures=int(k > 1))
               for i in reversed(range(episodes))]  # Out of order: paired by episode.
    wins = sum(r['success'] for r in records)
    return dict(records=records, successes=wins, success_rate=wins / episodes,
                success_ci95=[0.0, 1.0])

  monkeypatch.setattr(evaluation_suite, 'evaluate_policy', fake)
  spec = EvalSpec.from_config(smoke_config)
  rows = diagnostics.success_by_k(spec, None, [1, 4, 16], episodes=10, seed=0)
  # The actor-prior share of the config (2 of 8) kept; none for K = 1.
  assert seen == [(1, 0, 'plan', 'held_out'), (4, 1, 'plan', 'held_out'),
                  (16, 4, 'plan', 'held_out')]
  assert [(r['k'], r['prior'], r['successes']) for r in rows] == [(1, 0, 1), (4, 1, 4),
                                                                   (16, 4, 10)]
  m = rows[0]['vs_largest_k']
  assert (m['n'], m['a_only'], m['b_only']) == (10, 0, 9)
  assert m['p_value'] == pytest.approx(2 / 2 ** 9)
  assert rows[2]['vs_largest_k']['p_value'] == 1.0  # Itself.
  assert rows[0]['departure_share'] == 0.0 and rows[1]['departure_share'] == pytest.approx(0.1)
  assert rows[1]['success_with_departures'] == [4, 10]
  assert spec.act.plan.num_candidates == 8  # The caller's spec is left as it was.


def test_markdown_table_rows():
  row = dict(k=4, prior=1, successes=3, episodes=10, success_rate=0.3, success_ci95=[0.1, 0.6],
             vs_largest_k=dict(n=10, a_only=1, b_only=5, p_value=0.21875), departure_share=0.25,
             success_with_departures=[2, 6], success_without_departures=[1, 4])
  report = dict(workdir='runs/x', step=100, k=4,
                correlation=dict(windows=12, spearman_model=0.5, spearman_encoder=0.75),
                success_by_k=[row], candidate_wins={'proposal': 0.75, 'actor_prior': 0.25})
  lines = diagnostics.markdown(report).splitlines()
  assert lines[0] == '# Objective diagnostics: runs/x (step 100)'
  assert 'dynamics-model rollout 0.500, encoder latents 0.750.' in lines[2]
  assert ('| 4 | 1 | 3/10 = 0.30 | [0.10, 0.60] | 1 / 5 | 0.22 | 0.25 | 2/6 / 1/4 |'
          in lines)
  assert lines[-1].endswith(': proposal 0.75, actor_prior 0.25.')


def test_candidate_kinds_counted_over_start_states(monkeypatch, smoke_config):
  """planner.build_plan stubbed: the winning kind of each plan is its key's index mod 2."""
  from ld_mpc_jax.plan import planner

  class Out:
    def __init__(self, kind):
      self.kind = kind

  monkeypatch.setattr(planner, 'build_plan', lambda model, plan: lambda params, z, key: Out(
      int(jax.random.key_data(key)[-1]) % 2))
  monkeypatch.setattr(diagnostics.models, 'encode', lambda params, obs: obs)
  wins = diagnostics.candidate_wins(EvalSpec.from_config(smoke_config).act, None,
                                    np.zeros((4, 3)))
  assert list(wins) == list(planner.CANDIDATE_KINDS)
  assert wins[planner.CANDIDATE_KINDS[0]] == 0.5 and wins[planner.CANDIDATE_KINDS[1]] == 0.5
  assert sum(wins.values()) == 1.0


def test_summarize_trace_reads_last_and_largest_terms():
  from ld_mpc_jax.analysis.diagnostics import summarize_trace, trace_markdown
  steps = [dict(reward=r, in_place_reward=p, success=0.0) for r, p in
           [(1.0, 0.1), (4.0, 0.8), (2.0, 0.3)]]
  s = summarize_trace(steps, last=2)
  assert s['decisions'] == 3 and s['ret'] == 7.0 and s['max_reward'] == 4.0
  assert s['mean_reward_last'] == 3.0
  assert s['in_place_reward_last'] == 0.3 and s['in_place_reward_max'] == 0.8
  assert 'success_last' not in s  # The outcome is the record's, not a reward term.
  md = trace_markdown([dict(policy='actor', episode=3, success=0, first_success=None, **s)])
  assert '| 3 | actor | no | 3 | 7 | 4.00 | 3.00 | 0.30 / 0.80 |' in md
  with pytest.raises(ValueError, match='at least one step'):
    summarize_trace([])


def test_gain_parts_add_up_to_the_objective(smoke_config, smoke_params):
  """The reward part plus the value part is J at pessimism 0 of the same rollout, for the
  executed sequence and the actor prior acting along its own rollout."""
  from ld_mpc_jax.model import models, objective
  from ld_mpc_jax.plan import planner
  nets = models.build_networks(ModelSettings.from_config(smoke_config))
  z = models.encode(smoke_params, np.zeros(39, np.float32))
  seq = jax.random.uniform(jax.random.key(3), (smoke_config.horizon, smoke_config.action_dim),
                           minval=-1, maxval=1)
  key = jax.random.key(5)
  act = EvalSpec.from_config(smoke_config).act
  r, v = diagnostics.gain_parts(act, nets, draws=1)(smoke_params, z, seq, key)
  roll = planner.make_rollout(ModelSettings.from_config(smoke_config), dataclasses.replace(
      PlanSettings.from_config(smoke_config), num_prior_candidates=1), nets)
  acts, lats = roll(smoke_params, z, seq[None], jax.random.split(key, 1)[0])
  j = objective.make_member_scores(ModelSettings.from_config(smoke_config), nets,
      smoke_config.plan.progress_weight)(smoke_params, lats, acts).mean(0)
  np.testing.assert_allclose(r + v, j, rtol=1e-5, atol=1e-4)
  np.testing.assert_allclose(acts[0], seq)  # The executed sequence is rolled as given.
  assert not np.allclose(r, 0.0)


def test_summarize_gains_from_hand_built_decisions():
  from ld_mpc_jax.analysis.diagnostics import gains_markdown, summarize_gains
  dec = [dict(t=0, departed=False),
         dict(t=1, departed=True, reward_gain=1.0, value_gain=3.0, j_prior=100.0),
         dict(t=2, departed=True, reward_gain=2.0, value_gain=-1.0, j_prior=-50.0),
         dict(t=3, departed=False)]
  s = summarize_gains(dict(episode=7, success=0, first_success=None, decisions=dec))
  assert s['decisions'] == 4 and s['departure_share'] == 0.5
  assert s['reward_gain'] == 1.5 and s['value_gain'] == 1.0 and s['value_led'] == 0.5
  assert s['relative_gain'] == pytest.approx(np.median([4 / 100, 1 / 50]))
  assert s['reversed'] == 0.0
  assert '| 7 | no | 4 | 0.50 | 1.50 | 1.00 | 0.50 | 0.0300 | 0.00 |' in gains_markdown([s])
  dec[2]['value_gain'] = -3.0  # Its gain, 2 - 3, is now negative.
  assert summarize_gains(dict(episode=7, success=0, first_success=None,
                              decisions=dec))['reversed'] == 0.5
  none = summarize_gains(dict(episode=1, success=1, first_success=9, decisions=dec[:1]))
  assert none['departure_share'] == 0.0 and np.isnan(none['value_gain'])


def test_departure_gains_runs_the_evaluation_episodes(smoke_config, smoke_params):
  """Three decisions of held-out episode 1: one row per decision with the environment's terms,
  and the gain parts on exactly the decisions that departed."""
  smoke_config.eval.max_episode_steps = 6  # Three decisions at action repeat 2.
  spec = EvalSpec.from_config(smoke_config)
  out = diagnostics.departure_gains(spec, smoke_params, [1], seed=0, num_episodes=2, draws=2)
  assert len(out) == 1 and out[0]['episode'] == 1
  rows = out[0]['decisions']
  assert [r['t'] for r in rows] == [0, 1, 2]
  assert all('in_place_reward' in r and 'reward' in r for r in rows)
  assert all(('value_gain' in r) == r['departed'] for r in rows)
  assert any(r['departed'] for r in rows)  # The untrained argmax leaves the actor prior.
  records = evaluation_suite.evaluate_policy(spec, smoke_params, 'plan', 2, 0,
                                             only=[1])['records']
  assert records[0]['length'] == 3 and out[0]['success'] == records[0]['success']


def test_departure_gains_cli_summarizes_a_saved_file_and_fails_in_one_line(tmp_path):
  import json
  import os
  import subprocess
  import sys
  dec = [dict(t=0, departed=True, reward_gain=1.0, value_gain=-2.0, j_prior=10.0)]
  path = tmp_path / 'gains.json'
  path.write_text(json.dumps(dict(episodes=[dict(episode=4, success=1, first_success=1,
                                                 decisions=dec)])))
  repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  run = lambda *args: subprocess.run([sys.executable, '-m', 'experiments.diagnose', 'departures', *args],
                                     capture_output=True, text=True, timeout=120, cwd=repo)
  out = run(f'--summarize={path}')
  assert out.returncode == 0, out.stderr[-1000:]
  assert '| 4 | yes (1) | 1 | 1.00 | 1.00 | -2.00 | 0.00 | -0.1000 | 1.00 |' in out.stdout
  bad = run('--episodes=1')
  assert bad.returncode != 0 and 'give --workdir and --episodes' in bad.stderr
  assert len(bad.stderr.strip().splitlines()) == 1
