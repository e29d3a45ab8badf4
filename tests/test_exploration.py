"""ld_mpc_jax.online (settings, schedule): the acting planner's settings, the annealed std of the executed-action
noise and its correlated (AR(1)) draws, and the intrinsic exploration term in J while acting
(objective.Intrinsic: optimism over the value members, the dynamics draws' disagreement, annealed)."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open_online
from ld_mpc_jax import validate_config
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.model.settings import PlanSettings
from ld_mpc_jax.online import schedule
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.model import models, objective
from ld_mpc_jax.plan import planner, search


def acting_plan(config):
  """The acting planner's settings of `config` (OnlineSettings.acting_plan)."""
  return OnlineSettings.from_config(config).acting_plan(PlanSettings.from_config(config))


def acting_schedule(config, learn_start):
  return schedule.ActingSchedule(OnlineSettings.from_config(config), learn_start)


def test_acting_plan_is_the_plans_with_the_online_noise_and_pessimism():
  c = door_open_online.get_config('smoke')
  c.online.action_noise_std, c.online.prior_noise_std, c.online.act_pessimism = 0.3, 0.4, -0.5
  c.plan.safe_selection, c.online.act_safe_selection = True, False  # Safe only in evaluation.
  plan = c.plan.to_dict()
  acting = acting_plan(c)
  assert (acting.action_noise_std, acting.prior_noise_std, acting.pessimism,
          acting.safe_selection) == (0.3, 0.4, -0.5, False)
  assert c.plan.to_dict() == plan  # The evaluation's config is left as it was.
  others = lambda p: {k: v for k, v in p.items() if k not in (
      'action_noise_std', 'prior_noise_std', 'pessimism', 'safe_selection', 'safe_confirm',
      'fallback_drop')}  # The gates: inert without safe selection, and zeroed with it off.
  assert others(dataclasses.asdict(acting)) == others(plan)


def test_acting_searches_with_its_own_settings_and_evaluation_with_the_plans():
  c = door_open_online.get_config('cpu')
  assert (c.online.act_num_gaussian, c.online.act_iterations) == (32, 3)  # As the presets act.
  assert (c.plan.num_gaussian, c.plan.iterations) == (0, 0)  # Evaluation: proposal and prior.
  acting = acting_plan(c)
  assert (acting.num_gaussian, acting.iterations) == (32, 3)
  assert (c.plan.num_gaussian, c.plan.iterations) == (0, 0)


def test_acting_keeps_the_safe_selection_gates_only_when_asked():
  c = door_open_online.get_config('cpu')
  c.plan.safe_selection, c.plan.safe_confirm, c.plan.fallback_drop = True, True, 0.1
  acting = acting_plan(c)  # online.act_safe_selection is off in the presets.
  assert not (acting.safe_selection or acting.safe_confirm)
  assert acting.fallback_drop == 0
  c.online.act_safe_selection = True
  acting = acting_plan(c)
  assert acting.safe_confirm and acting.fallback_drop == 0.1


def test_the_cpu_preset_evaluates_without_the_search_it_acts_with():
  c = door_open_online.get_config('cpu')
  assert (c.critic.log_std_map, c.plan.num_gaussian, c.plan.iterations) == ('tanh', 0, 0)
  acting = acting_plan(c)
  assert (acting.num_gaussian, acting.iterations) == (32, 3)  # Acting still searches.
  assert (acting.pessimism, c.online.exec_noise_corr, c.gamma) == (-1.0, 0.85, 0.95)


def test_removed_presets_say_what_to_use():
  with pytest.raises(ValueError, match="preset 'cpu_tanh' is now ':cpu'"):
    door_open_online.get_config('cpu_tanh')
  with pytest.raises(ValueError, match="'cpu_optimistic' was removed .*e421b33"):
    door_open_online.get_config('cpu_optimistic')


def test_executed_noise_anneals_linearly():
  c = door_open_online.get_config('cpu')
  start, end = c.online.exec_noise_start, c.online.exec_noise_end
  noise = acting_schedule(c, 1_600).executed_noise
  assert noise(0) == pytest.approx(start)  # Before learning starts.
  assert noise(1_600) == pytest.approx(start)
  mid = (1_600 + c.online.env_steps) // 2
  assert noise(mid) == pytest.approx((start + end) / 2)
  assert noise(c.online.env_steps) == pytest.approx(end)
  # online.schedule_steps moves where every schedule ends (a run continued to more steps).
  c.online.schedule_steps = c.online.env_steps
  c.online.env_steps *= 2
  noise = acting_schedule(c, 1_600).executed_noise
  assert noise(mid) == pytest.approx((start + end) / 2)
  assert noise(c.online.schedule_steps) == pytest.approx(end)
  c.online.act_schedule, c.online.act_pessimism, c.online.act_pessimism_end = 'linear', -1.0, 0.0
  at = acting_schedule(c, 0).exploration
  assert at(c.online.schedule_steps)[0] == pytest.approx(0.0)
  c.online.schedule_steps = 0
  at = acting_schedule(c, 0).exploration
  assert at(c.online.env_steps // 2)[0] == pytest.approx(-0.5)
  c.online.schedule_steps = -1
  with pytest.raises(ValueError, match='schedule_steps must be an integer >= 0'):
    validate_config(c)


def test_correlated_noise_has_the_annealed_std_and_its_correlation():
  """AR(1) executed-action noise (`online.exec_noise_corr`): stationary std = executed_noise,
  lag-one autocorrelation = the configured correlation."""
  c = door_open_online.get_config('cpu')
  c.online.exec_noise_start = c.online.exec_noise_end = 0.3
  std = acting_schedule(c, 1_600).executed_noise(5_000)
  rng, noise, draws = np.random.default_rng(0), np.zeros((4, 4)), []
  for _ in range(5_000):
    noise = schedule.ar1_noise(noise, std, c.online.exec_noise_corr, rng)
    draws.append(noise)
  x = np.stack(draws[100:])  # [T, 4, 4], past the start-up from zero.
  assert np.std(x) == pytest.approx(0.3, rel=0.05)
  lag1 = np.mean(x[1:] * x[:-1]) / np.mean(x * x)
  assert lag1 == pytest.approx(0.85, abs=0.02)


# The intrinsic exploration term in J while acting (objective.Intrinsic, online.act_*).


def _intrinsic(pessimism, disagreement):
  return objective.Intrinsic(pessimism=jnp.float32(pessimism),
                             disagreement=jnp.float32(disagreement))


def test_intrinsic_term_is_zero_for_a_deterministic_ensemble_and_grows_with_disagreement():
  rng = np.random.default_rng(0)
  base = jnp.asarray(rng.normal(size=(1, 1, 6)) * 100.0, jnp.float32)  # [R, M, N]: J's scale.
  agree = jnp.broadcast_to(base, (3, 5, 6))  # Three dynamics draws, five members, all agree.
  latents = jnp.broadcast_to(jnp.asarray(rng.normal(size=(1, 6, 4, 8)), jnp.float32),
                             (3, 6, 4, 8))  # [R, N, H+1, D]
  bonus = _intrinsic(-2.0, 50.0)
  assert np.all(np.asarray(objective.intrinsic_term(agree, latents, bonus, 0.9)) == 0.0)
  # Members that disagree: the optimism bonus is |pessimism| x their std, growing with it.
  noise = jnp.asarray(rng.normal(size=(3, 5, 6)), jnp.float32)
  terms = [np.asarray(objective.intrinsic_term(agree + s * noise, latents, _intrinsic(-2.0, 0.0),
                                               0.9)) for s in (0.5, 1.0, 2.0)]
  np.testing.assert_allclose(terms[1], 2.0 * np.mean(np.std(np.asarray(noise), axis=1), 0),
                             rtol=1e-4)
  assert np.all(terms[0] > 0) and np.all(terms[1] > terms[0]) and np.all(terms[2] > terms[1])
  # Draws that disagree about the next latents: sum_i gamma^i x variance over draws, by hand.
  offset = jnp.asarray([-1.0, 0.0, 1.0])[:, None, None, None]  # Variance 2/3 per dimension.
  moved = latents + offset * jnp.asarray([0.0, 1.0, 2.0, 3.0])[None, None, :, None]
  d = np.asarray(objective.intrinsic_term(agree, moved, _intrinsic(0.0, 1.0), 0.9))
  np.testing.assert_allclose(d, (2 / 3) * (1.0 + 0.9 * 4.0 + 0.81 * 9.0), rtol=1e-5)
  wider = np.asarray(objective.intrinsic_term(agree, latents + 2 * (moved - latents),
                                              _intrinsic(0.0, 1.0), 0.9))
  np.testing.assert_allclose(wider, 4 * d, rtol=1e-5)


def _members(spread):
  """A score function of M = 5 members: the toy J = first action's first coordinate, plus
  member offsets of std proportional to `spread` (0: a deterministic ensemble)."""
  offsets = spread * jnp.asarray([-2.0, -1.0, 0.0, 1.0, 2.0])[:, None]
  return lambda params, latents, actions: actions[None, :, 0, 0] * 10.0 + offsets


def test_plan_with_an_intrinsic_term_and_agreeing_members_scores_as_without(
    smoke_config, smoke_params):
  z = models.encode(smoke_params, np.ones(smoke_config.obs_dim, np.float32))
  plan = planner.make_plan(smoke_config, _members(0.0))
  key = jax.random.key(3)
  plain, bonus = plan(smoke_params, z, key), plan(smoke_params, z, key, None, 0.0, None,
                                                   _intrinsic(-1.0, 0.0))
  np.testing.assert_array_equal(bonus.scores, plain.scores)
  np.testing.assert_array_equal(bonus.action, plain.action)
  # Disagreeing members: every candidate gains |pessimism| x the members' std (sqrt(2) x 0.5;
  # the plan's own pessimism, smoke's 1, is subtracted in both).
  split = planner.make_plan(smoke_config, _members(0.5))
  plain, bonus = split(smoke_params, z, key), split(smoke_params, z, key, None, 0.0, None,
                                                    _intrinsic(-1.0, 0.0))
  np.testing.assert_allclose(bonus.scores - plain.scores, np.sqrt(2.0) * 0.5, rtol=1e-5)


def test_while_acting_the_plan_reports_the_proposals_share_of_the_elites_refinement_starts_from(
    smoke_config, smoke_params):
  """The first round mixes the proposal's, the Gaussians' and the actor prior's candidates; one
  refinement round starts from its `plan.num_elites` best, whose share of the proposal's is
  reported while acting (by hand from the first round's scores, which the output keeps first)."""
  c = smoke_config
  c.plan.num_candidates, c.plan.num_gaussian, c.plan.num_prior_candidates = 6, 3, 2
  c.plan.first_round, c.plan.num_elites = ('proposal', 'gaussian'), 4
  c.plan.iterations, c.plan.num_refine = 1, 4
  p = PlanSettings.from_config(c)
  z = models.encode(smoke_params, np.ones(c.obs_dim, np.float32))
  plan = planner.make_plan(c, _members(0.0))
  assert float(plan(smoke_params, z, jax.random.key(0)).proposal_elites) == -1.0  # Not acting.
  kinds = np.asarray([search.CANDIDATES.index(k) for k, n in search.first_round_counts(p)
                      for _ in range(n)] + [search.CANDIDATES.index('actor_prior')] * 2)
  shares = []
  for seed in range(4):
    out = plan(smoke_params, z, jax.random.key(seed), None, 0.0, None, _intrinsic(0.0, 0.0))
    first = np.asarray(out.scores)[:len(kinds)]  # Then the refined round's elites.
    best = np.argsort(-first, kind='stable')[:4]
    shares.append(np.mean(kinds[best] == search.CANDIDATES.index('proposal')))
    assert float(out.proposal_elites) == pytest.approx(shares[-1])
  assert len(set(shares)) > 1 or 0.0 < shares[0] < 1.0  # Not a constant by construction.


@pytest.mark.parametrize('dynamics_type', ['mlp', 'diffusion_ar'])
def test_the_dynamics_draws_disagree_only_where_the_dynamics_are_stochastic(smoke_config,
                                                                            dynamics_type):
  """Plan2Explore's term on the planner's own rollouts: 0 under the deterministic MLP dynamics,
  positive for every candidate under the diffusion dynamics' draws."""
  c = smoke_config
  c.model.dynamics_type, c.plan.dynamics_draws = dynamics_type, 3
  params = models.init_params(c, jax.random.key(0))
  z = models.encode(params, np.ones(c.obs_dim, np.float32))
  plan = planner.make_plan(c, _members(0.0))
  plain = plan(params, z, jax.random.key(1))
  bonus = plan(params, z, jax.random.key(1), None, 0.0, None, _intrinsic(0.0, 5.0))
  gain = np.asarray(bonus.scores - plain.scores)
  if dynamics_type == 'mlp':
    np.testing.assert_array_equal(gain, 0.0)
  else:
    assert np.all(gain > 1e-3)


def test_changing_the_traced_intrinsic_term_never_recompiles(smoke_config, smoke_params):
  traces = []
  def counting(params, latents, actions):
    traces.append(1)  # Runs once per trace, never when a compiled plan runs.
    return _members(0.5)(params, latents, actions)
  plan = planner.make_plan(smoke_config, counting)
  z = models.encode(smoke_params, np.ones(smoke_config.obs_dim, np.float32))
  c = exploration_config('linear')
  scores = []
  for steps in (c.online.seed_steps, 3_000, c.online.env_steps):  # The annealed schedule.
    out = plan(smoke_params, z, jax.random.key(0), None, 0.0, None,
               acting_schedule(c, c.online.seed_steps).intrinsic(steps))
    scores.append(np.asarray(out.scores))
    if steps == c.online.seed_steps:
      first = (len(traces), plan._cache_size())
  assert (len(traces), plan._cache_size()) == first  # Traced once, whatever the values.
  assert not np.allclose(scores[0], scores[-1])  # And the values did change J.


def exploration_config(schedule):
  c = door_open_online.get_config('cpu')
  c.online.act_schedule = schedule
  c.online.act_pessimism, c.online.act_pessimism_end = -1.0, -0.2
  c.online.act_disagreement, c.online.act_disagreement_end = 40.0, 0.0
  c.online.act_dynamics_draws = 4
  return c


def test_the_schedule_starts_at_the_first_planner_wave_and_ends_at_env_steps():
  c = exploration_config('linear')
  start, end = c.online.seed_steps, c.online.env_steps  # From scratch: after the seed waves.
  at = lambda steps: acting_schedule(c, start).exploration(steps)
  assert at(0) == at(start) == pytest.approx((-1.0, 40.0))
  assert at((start + end) // 2) == pytest.approx((-0.6, 20.0))
  assert at(end) == at(end + 800) == pytest.approx((-0.2, 0.0))
  # Linear: acting's pessimism is the traced term alone; the acting config's is 0.
  bonus = acting_schedule(c, start).intrinsic(end)
  assert (float(bonus.pessimism), float(bonus.disagreement)) == pytest.approx((-0.2, 0.0))
  acting = acting_plan(c)
  assert (acting.pessimism, acting.dynamics_draws) == (0.0, 4)
  assert (c.plan.pessimism, c.plan.dynamics_draws) == (1.0, 1)  # Evaluation's, unchanged.
  # Constant (the default): the start values throughout; the pessimism stays a setting.
  c = exploration_config('constant')
  schedule = acting_schedule(c, start)
  assert schedule.exploration(end) == pytest.approx((-1.0, 40.0))
  bonus = acting_schedule(c, start).intrinsic(end)
  assert (float(bonus.pessimism), float(bonus.disagreement)) == pytest.approx((0.0, 40.0))
  assert acting_plan(c).pessimism == -1.0


def test_the_first_planner_wave_follows_the_actor_prior_seed_waves():
  c = door_open_online.get_config('cpu')
  first = lambda learn_start: acting_schedule(c, learn_start).plan_start
  assert first(c.online.seed_steps) == c.online.seed_steps  # From scratch.
  c.online.demos = 5  # Learning starts at once; the planner acts from the first wave ...
  assert first(0) == 0
  c.online.demo_seed_actor = True  # ... or after the actor prior's seed waves.
  assert first(0) == c.online.seed_steps


@pytest.mark.parametrize('overrides,match', [
    (dict(act_schedule='cosine'), 'act_schedule'),
    (dict(act_disagreement=1.0), 'act_dynamics_draws >= 2'),
    (dict(act_schedule='linear', act_disagreement_end=1.0), 'act_dynamics_draws >= 2'),
    (dict(act_dynamics_draws=-1), 'act_dynamics_draws'),
])
def test_bad_intrinsic_settings_fail_in_one_line(overrides, match):
  c = door_open_online.get_config('cpu')
  c.online.update(overrides)
  with pytest.raises(ValueError, match=match):
    validate_config(c)


def test_defaults_add_no_intrinsic_term_and_old_runs_load_them(tmp_path):
  c = door_open_online.get_config('cpu')
  bonus = acting_schedule(c, c.online.seed_steps).intrinsic(50_000)
  assert (float(bonus.pessimism), float(bonus.disagreement)) == (0.0, 0.0)
  assert acting_plan(c).pessimism == c.online.act_pessimism  # As before.
  raw = json.loads(c.to_json_best_effort())
  for name in ('act_schedule', 'act_pessimism_end', 'act_disagreement', 'act_disagreement_end',
               'act_dynamics_draws', 'act_proposal'):
    del raw['online'][name]  # Saved before these fields existed,
  del raw['version']  # and so before configs had a version.
  (tmp_path / 'config.json').write_text(json.dumps(raw))
  loaded = checkpointing.load_config(str(tmp_path))
  assert loaded.online.to_dict() == c.online.to_dict()


def test_acting_without_the_proposal_needs_other_candidates():
  c = door_open_online.get_config('smoke')  # K = 4 proposal sequences, no actor prior.
  c.online.act_proposal = False
  with pytest.raises(ValueError, match='act_proposal=False leaves no candidate'):
    validate_config(c)
  c.plan.num_prior_candidates = 2
  validate_config(c)
  assert acting_plan(c).num_candidates == 2  # The actor prior's alone.
  assert c.plan.num_candidates == 4  # Evaluation keeps the proposal's.
