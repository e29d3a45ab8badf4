"""ld_mpc_jax.plan.search inside plan(): refinement, safe selection, softmax selection, acting noise."""

import jax
import jax.numpy as jnp
import numpy as np
import ml_collections
import pytest

from ld_mpc_jax import encode, make_plan
from ld_mpc_jax.plan import search
from ld_mpc_jax.plan.search import CANDIDATE_KINDS
from ld_mpc_jax.model.settings import PlanSettings
from ld_mpc_jax.plan.modes import ActSettings

TARGET = jnp.array([0.6, -0.4, 0.2, -0.8])  # The toy optimum: this action at every step.


def toy_score(params, latents, actions):
  """J = -sum over steps of ||a_i - TARGET||^2: the best sequence repeats TARGET."""
  return -jnp.sum((actions - TARGET) ** 2, axis=(-2, -1))


@pytest.fixture
def z(smoke_params):
  return encode(smoke_params, np.linspace(-1, 1, 39).astype(np.float32))


def search_config(smoke_config, iterations):
  c = ml_collections.ConfigDict(smoke_config.to_dict())
  c.plan.num_candidates, c.plan.num_prior_candidates = 6, 2
  c.plan.num_gaussian, c.plan.gaussian_std = 8, 2.0
  c.plan.iterations, c.plan.num_refine, c.plan.num_elites = iterations, 32, 4
  return c


def test_refinement_moves_toward_the_toy_optimum(smoke_config, smoke_params, z):
  first = make_plan(search_config(smoke_config, 0), toy_score)
  refined = make_plan(search_config(smoke_config, 5), toy_score)
  gains, kinds = [], []
  for seed in range(5):
    a = first(smoke_params, z, jax.random.key(seed))
    b = refined(smoke_params, z, jax.random.key(seed))
    gains.append(float(b.scores[b.index] - a.scores[a.index]))
    kinds.append(CANDIDATE_KINDS[int(b.kind)])
    assert int(b.iteration) >= 1 or kinds[-1] != 'refined'
  # Refinement keeps the first round's elites, so it is never worse, and it gets closer.
  assert min(gains) >= 0.0 and np.mean(gains) > 0.1
  assert kinds.count('refined') >= 4
  b = refined(smoke_params, z, jax.random.key(0))
  assert float(jnp.max(jnp.abs(b.sequence - TARGET))) < 0.5
  assert b.candidates.shape[0] == 6 + 8 + 4  # The first round, then the final elites.


def test_elite_moments_weight_the_best():
  actions = jnp.stack([jnp.zeros((2, 1)), jnp.ones((2, 1))])
  mean, std = search.elite_moments(actions, jnp.array([0.0, 100.0]), 0.5, 0.05, 2.0)
  np.testing.assert_allclose(mean, 1.0, atol=1e-6)
  np.testing.assert_allclose(std, 0.05, atol=1e-6)  # Clipped at the minimum.
  mean, _ = search.elite_moments(actions, jnp.array([0.0, 0.0]), 0.5, 0.05, 2.0)
  np.testing.assert_allclose(mean, 0.5, atol=1e-6)


def safe_config(smoke_config, margin, selection='argmax'):
  c = smoke_config
  c.plan.num_candidates, c.plan.num_prior_candidates = 6, 2
  c.plan.safe_selection, c.plan.safe_margin, c.plan.selection = True, margin, selection
  # Safe selection alone: no K scaling of the margin, no confirmation, no fallback (the
  # defaults are the recommended setting's; the tests below switch each on by itself).
  c.plan.safe_margin_scaling, c.plan.safe_confirm, c.plan.fallback_drop = 'none', False, 0.0
  c.plan.confirm_draws, c.plan.confirm_margin, c.plan.fallback_floor = 1, -1.0, 0.0
  return c


def actor_sequence(plan_fn, params, z, key):
  """The actor prior's own sequence: index K - P (no Gaussian set)."""
  out = plan_fn(params, z, key)
  return out.candidates[4], out


def test_equal_scores_return_the_actor_prior(smoke_config, smoke_params, z):
  flat = lambda params, latents, actions: jnp.zeros(actions.shape[0])
  plan = make_plan(safe_config(smoke_config, 0.0), flat)
  seq, out = actor_sequence(plan, smoke_params, z, jax.random.key(3))
  np.testing.assert_array_equal(out.sequence, seq)
  assert not bool(out.departed) and CANDIDATE_KINDS[int(out.kind)] == 'actor_prior'


def noisy_members(params, latents, actions):
  """[M = 5, K]: the toy J plus member noise of std 1 (a disagreeing ensemble)."""
  noise = jax.random.normal(jax.random.key(42), (5, actions.shape[0]))
  return toy_score(params, latents, actions)[None] + noise


def test_large_margin_always_keeps_the_actor_prior(smoke_config, smoke_params, z):
  plan = make_plan(safe_config(smoke_config, 1e6), noisy_members)
  for seed in range(4):
    seq, out = actor_sequence(plan, smoke_params, z, jax.random.key(seed))
    np.testing.assert_array_equal(out.action, jnp.clip(seq[0], -1, 1))
    assert not bool(out.departed)


def test_zero_margin_is_the_argmax(smoke_config, smoke_params, z):
  plan = make_plan(safe_config(smoke_config, 0.0), noisy_members)
  departed = []
  for seed in range(4):
    out = plan(smoke_params, z, jax.random.key(seed))
    assert int(out.index) == int(jnp.argmax(out.scores))
    np.testing.assert_array_equal(out.sequence, out.candidates[out.index])
    departed.append(bool(out.departed))
  assert any(departed)


def test_softmax_selection_weights_the_elites(smoke_config, smoke_params, z):
  c = smoke_config
  c.plan.num_candidates, c.plan.num_prior_candidates, c.plan.selection = 6, 0, 'softmax'
  c.plan.num_elites, c.plan.temperature = 3, 1e-6  # Nearly equal weights over 3 elites.
  out = make_plan(c, toy_score)(smoke_params, z, jax.random.key(0))
  top = np.argsort(-np.asarray(out.scores))[:3]
  np.testing.assert_allclose(out.sequence, np.mean(np.asarray(out.candidates)[top], 0),
                             atol=1e-5)


def test_action_noise_only_when_asked_and_no_recompile(smoke_config, smoke_params, z):
  plan = make_plan(smoke_config)
  key = jax.random.key(5)
  quiet = plan(smoke_params, z, key)
  np.testing.assert_array_equal(quiet.action, jnp.clip(quiet.sequence[0], -1, 1))
  noisy, sizes = [], []
  for std in (0.3, 0.1, 0.05):
    noisy.append(plan(smoke_params, z, key, None, std))
    sizes.append(plan._cache_size())
  for out in noisy:
    np.testing.assert_array_equal(out.sequence, quiet.sequence)  # Same plan, noisy action.
    assert float(jnp.max(jnp.abs(out.action - quiet.action))) > 1e-3
  assert sizes[0] == sizes[-1]  # Annealing the noise never recompiles.


def test_acting_policy_has_no_noise_unless_set(smoke_config, smoke_params):
  from ld_mpc_jax.plan.agent import BatchAgentPolicy
  from ld_mpc_jax.envs import goals
  obs = np.zeros((2, 39), np.float32)
  policy = BatchAgentPolicy(ActSettings.from_config(smoke_config), smoke_params, 'plan', seed=0,
                            chunk=0)
  eps = [goals.Episode('x', i, 0, i, '', None) for i in range(2)]
  policy.start(eps)
  quiet = policy(obs, 0, np.ones(2, bool))
  assert policy.action_noise == 0.0 and policy.last_info.shape == (2, 7)
  policy.start(eps)
  policy.action_noise = 0.5
  noisy = policy(obs, 0, np.ones(2, bool))
  assert np.max(np.abs(noisy - quiet)) > 1e-3


def test_bad_search_settings_fail_in_one_line(smoke_config):
  c = smoke_config
  c.plan.safe_selection, c.plan.num_prior_candidates = True, 0
  with pytest.raises(ValueError, match='num_prior_candidates >= 1'):
    make_plan(c)
  c.plan.safe_selection, c.plan.selection = False, 'best'
  with pytest.raises(ValueError, match='selection must be one of'):
    make_plan(c)


def _target_draws(model, plan, nets, propose):
  """A toy first-round kind: `num` copies of TARGET, jittered by 0.01."""
  shape = (3, model.horizon, model.action_dim)

  def draw(params, z, prop_key, noise_key, init):
    eps = jax.random.normal(jax.random.fold_in(noise_key, 99), shape)
    return jnp.clip(TARGET + 0.01 * eps, -1.0, 1.0)
  return draw


def test_a_candidate_kind_registered_here_joins_the_first_round(smoke_config, smoke_params, z):
  """A new first-round kind is one registry entry and its name in `plan.first_round`."""
  search.CANDIDATES.register('toy_target', search.CandidateKind(
      'three sequences near TARGET', lambda plan: 3, _target_draws))
  try:
    c = search_config(smoke_config, 0)
    c.plan.first_round = ('proposal', 'gaussian', 'toy_target')
    out = make_plan(c, toy_score)(smoke_params, z, jax.random.key(0))
    assert out.candidates.shape[0] == 4 + 8 + 3 + 2  # Proposal, Gaussian, toy, actor prior.
    toy = out.candidates[12:15]
    assert float(jnp.max(jnp.abs(toy - TARGET))) < 0.05
    assert search.CANDIDATES.names()[int(out.kind)] == 'toy_target'  # It wins on toy_score.
    c.plan.first_round = ('proposal', 'nosuch')
    with pytest.raises(ValueError, match="first_round must be one of .*'toy_target'"):
      make_plan(c, toy_score)
    c.plan.first_round = ('proposal', 'refined')
    with pytest.raises(ValueError, match="'refined' is not drawn in the first round"):
      make_plan(c, toy_score)
  finally:
    search.CANDIDATES.unregister('toy_target')


def test_first_round_counts_must_match_the_kinds_named(smoke_config, smoke_params, z):
  """Gaussian candidates asked for but left out of the first round fail at build time; a first
  round of the actor prior's candidates alone plans."""
  c = search_config(smoke_config, 0)
  c.plan.first_round = ('proposal',)
  with pytest.raises(ValueError, match="leaves out 'gaussian', which its settings give 8"):
    make_plan(c, toy_score)
  c.plan.num_gaussian, c.plan.num_candidates = 0, c.plan.num_prior_candidates
  out = make_plan(c, toy_score)(smoke_params, z, jax.random.key(0))
  assert out.candidates.shape[0] == c.plan.num_prior_candidates
  assert search.CANDIDATES.names()[int(out.kind)] == 'actor_prior'


def test_safe_softmax_gates_on_the_weighted_elites():
  """Under softmax the weighted elites must beat the anchor, not only the best elite."""
  actions = jnp.stack([jnp.full((2, 1), v) for v in (0.9, 0.1, 0.0)])  # [3, H=2, A=1]
  common = dict(anchor=2, margin=1.0, num_elites=3, temperature=0.0)  # Equal elite weights.

  def run(second, selection):
    members = jnp.array([[3.0, second[0], 0.0], [1.0, second[1], 0.0]])  # The anchor scores 0.
    return search.select(actions, members.mean(axis=0), members, safe=True,
                         selection=selection, **common)

  # The best elite beats the anchor by 2 > 1 x std([3, 1]) = 1: the argmax departs either way.
  for second in ((2.0, 2.0), (-3.0, -3.0)):
    seq, index, departed, _ = run(second, 'argmax')
    assert bool(departed) and int(index) == 0 and float(seq[0, 0]) == pytest.approx(0.9)
  # Softmax: the mean over the three elites gains (3 + 2) / 3 and (1 + 2) / 3 per member,
  # 4/3 > std = 1/3: it departs; with a poor second elite it gains -1/3: it keeps the anchor.
  seq, _, departed, _ = run((2.0, 2.0), 'softmax')
  assert bool(departed) and float(seq[0, 0]) == pytest.approx(1.0 / 3.0)
  seq, _, departed, _ = run((-3.0, -3.0), 'softmax')
  assert not bool(departed) and float(seq[0, 0]) == 0.0


def test_expected_max_matches_the_order_statistics_table():
  assert search.expected_max(1) == pytest.approx(0.0, abs=1e-6)
  assert search.expected_max(2) == pytest.approx(1 / np.sqrt(np.pi), abs=1e-5)
  # Tabulated expected maxima of n standard normals (Harter 1961).
  for n, value in ((3, 0.8463), (10, 1.5388), (100, 2.5076)):
    assert search.expected_max(n) == pytest.approx(value, abs=1e-3)
  with pytest.raises(ValueError, match='n >= 1'):
    search.expected_max(0)


def _departure_rate(k: int, margin: float, trials: int = 4000) -> float:
  """Share of decisions departing from the anchor when every candidate is equally good and the
  M = 5 members disagree by independent unit noise."""
  members = jax.random.normal(jax.random.key(0), (trials, 5, k))
  actions = jnp.zeros((k, 1, 1))
  depart = jax.vmap(lambda m: search.select(actions, m.mean(0), m, k - 1, True, margin,
                                            'argmax', 1, 0.5)[2])
  return float(jnp.mean(depart(members)))


def test_expected_max_scaling_holds_noise_departures_flat_in_k():
  fixed = {k: _departure_rate(k, 0.5) for k in (4, 64)}
  scaled = {k: _departure_rate(k, 0.5 * search.expected_max(k)) for k in (4, 64)}
  assert fixed[64] > fixed[4] + 0.3  # A fixed margin departs on noise more often at large K,
  assert abs(scaled[64] - scaled[4]) < 0.06  # the scaled one about as often at every K.


def test_effective_margin_counts_every_scored_candidate(smoke_config):
  c = search_config(smoke_config, 2)  # 6 + 8 first-round candidates, 2 rounds of 32.
  c.plan.safe_margin, c.plan.safe_margin_scaling = 2.0, 'none'
  assert search.num_scored(PlanSettings.from_config(c)) == 6 + 8 + 2 * 32
  assert search.effective_margin(PlanSettings.from_config(c)) == 2.0
  c.plan.safe_margin_scaling = 'expected_max'
  assert search.effective_margin(PlanSettings.from_config(c)) == pytest.approx(
      2.0 * search.expected_max(78))
  c.plan.safe_margin_scaling = 'sqrt'
  with pytest.raises(ValueError, match='safe_margin_scaling must be one of'):
    make_plan(c)


def test_plan_uses_the_scaled_margin(smoke_config, smoke_params, z):
  scaled = safe_config(ml_collections.ConfigDict(smoke_config.to_dict()), 5.0)
  scaled.plan.safe_margin_scaling = 'expected_max'
  fixed = safe_config(ml_collections.ConfigDict(smoke_config.to_dict()),
                      5.0 * search.expected_max(6))
  a_plan, b_plan = make_plan(scaled, noisy_members), make_plan(fixed, noisy_members)
  departed = []
  for seed in range(6):
    a, b = (f(smoke_params, z, jax.random.key(seed)) for f in (a_plan, b_plan))
    np.testing.assert_array_equal(a.action, b.action)
    assert bool(a.departed) == bool(b.departed)
    departed.append(bool(a.departed))
  assert 0 < sum(departed) < len(departed)  # The gate decides both ways here.


def rollout_noise_members(params, latents, actions):
  """[M = 5, K]: J that is pure rollout noise (a function of the final latent alone, which the
  dynamics draws change) plus member noise of std 0.1: no candidate is really better."""
  luck = 10.0 * jnp.sin(1e3 * jnp.sum(latents[:, -1], axis=-1))
  noise = 0.1 * jax.random.normal(jax.random.key(42), (5, actions.shape[0]))
  return luck[None] + noise


def test_confirmation_rejects_gains_that_fresh_draws_do_not_repeat(smoke_config, smoke_params,
                                                                   z):
  c = safe_config(smoke_config, 0.0)
  plain = make_plan(c, rollout_noise_members)
  c = ml_collections.ConfigDict(c.to_dict())
  c.plan.safe_confirm = True
  confirmed = make_plan(c, rollout_noise_members)
  plain_dep, conf_dep = [], []
  for seed in range(24):
    a, b = (f(smoke_params, z, jax.random.key(seed)) for f in (plain, confirmed))
    plain_dep.append(bool(a.departed))
    conf_dep.append(bool(b.departed))
    assert (not conf_dep[-1]) or plain_dep[-1]  # Confirmation only ever takes departures away.
    if not conf_dep[-1]:
      np.testing.assert_array_equal(b.sequence, b.candidates[4])  # The actor prior's own.
  # The first round's winner is the luckiest of six draws; a fresh pair of draws is a coin flip.
  assert sum(plain_dep) >= 16 and sum(conf_dep) <= 0.75 * sum(plain_dep)


def test_confirmation_keeps_real_gains(smoke_config, smoke_params, z):
  c = safe_config(smoke_config, 0.5)
  plain = make_plan(c, noisy_members)
  c = ml_collections.ConfigDict(c.to_dict())
  c.plan.safe_confirm = True
  confirmed = make_plan(c, noisy_members)
  for seed in range(6):  # The toy J does not depend on the rollout: a real gain repeats.
    a, b = (f(smoke_params, z, jax.random.key(seed)) for f in (plain, confirmed))
    np.testing.assert_array_equal(a.action, b.action)
    assert bool(a.departed) == bool(b.departed)


def test_confirmation_over_draws_counts_the_rollout_noise(smoke_config, smoke_params, z):
  """J that is pure rollout noise, members that agree: on one fresh rollout the members' spread
  is tiny and half of the departures pass; over 8 rollouts the spread includes the draws' noise
  and almost none does."""
  c = safe_config(smoke_config, 1.0)
  c.plan.safe_confirm = True
  passed = {}
  for draws in (1, 8):
    c = ml_collections.ConfigDict(c.to_dict())
    c.plan.confirm_draws = draws
    plan = make_plan(c, rollout_noise_members)
    passed[draws] = sum(bool(plan(smoke_params, z, jax.random.key(s)).departed)
                        for s in range(24))
  assert passed[1] >= 6 and passed[8] <= 2, passed


def test_confirmation_over_draws_keeps_real_gains(smoke_config, smoke_params, z):
  c = safe_config(smoke_config, 0.5)
  plain = make_plan(c, noisy_members)
  c = ml_collections.ConfigDict(c.to_dict())
  c.plan.safe_confirm, c.plan.confirm_draws = True, 4
  confirmed = make_plan(c, noisy_members)
  for seed in range(4):
    a, b = (f(smoke_params, z, jax.random.key(seed)) for f in (plain, confirmed))
    np.testing.assert_array_equal(a.action, b.action)


def test_confirm_margin_sets_the_confirmation_threshold(smoke_config, smoke_params, z):
  """Negative: the confirmation uses plan.safe_margin; a huge one confirms no departure; zero
  confirms every departure whose fresh mean gain is positive, more than margin 1 does."""
  c = safe_config(smoke_config, 1.0)
  c.plan.safe_confirm, c.plan.confirm_draws = True, 8
  plans = {}
  for margin in (-1.0, 1.0, 0.0, 1e6):
    c = ml_collections.ConfigDict(c.to_dict())
    c.plan.confirm_margin = margin
    plans[margin] = make_plan(c, rollout_noise_members)
  passed = {m: 0 for m in plans}
  for seed in range(24):
    out = {m: f(smoke_params, z, jax.random.key(seed)) for m, f in plans.items()}
    np.testing.assert_array_equal(out[-1.0].action, out[1.0].action)
    for m in plans:
      passed[m] += bool(out[m].departed)
  assert passed[-1.0] == passed[1.0] and passed[1e6] == 0, passed
  assert passed[0.0] >= passed[1.0] + 4, passed


def test_confirm_draws_must_be_positive(smoke_config):
  smoke_config.plan.confirm_draws = 0
  with pytest.raises(ValueError, match='confirm_draws must be >= 1'):
    make_plan(smoke_config)


def test_gates_act_only_with_safe_selection(smoke_config, smoke_params, z):
  """Confirmation and fallback are safe selection's gates: at their (recommended) defaults
  and without safe selection, the plan is the argmax's, and the planner carries no guard."""
  gates = lambda c: PlanSettings.from_config(c).gates
  c = smoke_config
  c.plan.num_prior_candidates = 2
  assert c.plan.safe_confirm and c.plan.fallback_drop > 0 and not c.plan.safe_selection
  assert gates(c) == (False, False)
  gated = make_plan(c)(smoke_params, z, jax.random.key(0))
  c = ml_collections.ConfigDict(c.to_dict())
  c.plan.safe_confirm, c.plan.fallback_drop = False, 0.0
  plain = make_plan(c)(smoke_params, z, jax.random.key(0))
  np.testing.assert_array_equal(gated.sequence, plain.sequence)
  assert int(gated.index) == int(plain.index) and not bool(gated.guard.fallen)
  c.plan.safe_selection, c.plan.safe_confirm, c.plan.fallback_drop = True, True, 0.1
  assert gates(c) == (True, True)


def test_score_draws_batch_the_same_draws_as_one_after_another():
  """Draw i rolls with fold_in(key, i), whether the draws run in one batch or a loop."""
  from ld_mpc_jax.model.objective import combine, make_score_draws
  def roll(params, z, proposals, key):
    lats = z + jax.random.normal(key, proposals.shape[:2] + (3,))
    return proposals + lats[..., :1], lats
  def members(params, lats, acts):  # [M = 2, N]
    return jnp.stack([jnp.sum(lats, axis=(1, 2)), jnp.sum(acts, axis=(1, 2)) - params])
  proposals, key, z = jnp.ones((5, 4, 2)), jax.random.key(3), jnp.float32(0.5)
  actions, scores, everything = make_score_draws(members, 6, 1.0, 0.9)(0.25, z, proposals, key,
                                                                         roll)
  loop = [roll(0.25, z, proposals, jax.random.fold_in(key, i)) for i in range(6)]
  expected = jnp.stack([members(0.25, lats, acts) for acts, lats in loop])  # [6, 2, 5]
  np.testing.assert_allclose(everything, expected.reshape(12, 5), rtol=1e-6)
  np.testing.assert_allclose(scores, jnp.mean(jax.vmap(lambda m: combine(m, 1.0))(expected), 0),
                             rtol=1e-6)
  np.testing.assert_allclose(actions, loop[0][0])
  assert float(jnp.std(expected[:, 0, 0])) > 0.1  # The draws differ.


def _levelled(params, latents, actions):
  """The toy J shifted by params['level']: the state's value, moved by the test."""
  return toy_score(params, latents, actions) + params['level']


def test_fallback_keeps_the_actor_prior_once_the_value_drops(smoke_config, smoke_params, z):
  """plan.fallback_drop: after the actor prior's J falls more than 10% below the episode's
  peak, the actor prior's sequence runs for the rest of the episode, even once J recovers."""
  c = safe_config(smoke_config, 0.0)
  c.plan.fallback_drop = 0.1
  guarded = make_plan(c, _levelled)
  c = ml_collections.ConfigDict(c.to_dict())
  c.plan.fallback_drop = 0.0
  free = make_plan(c, _levelled)
  guard, free_guard = None, None
  for t, level in enumerate([100.0, 95.0, 80.0, 100.0]):  # 95: 5% below; 80: 20% below.
    params = dict(smoke_params, level=jnp.float32(level))
    seq, out = actor_sequence(lambda *a: guarded(*a, guard=guard), params, z, jax.random.key(t))
    free_out = free(params, z, jax.random.key(t), guard=free_guard)
    guard, free_guard = out.guard, free_out.guard
    assert float(out.prior_score) == pytest.approx(float(_levelled(params, None, seq[None])[0]))
    assert bool(free_out.departed) and not bool(free_out.guard.fallen)
    if level > 90.0 and t < 2:  # Before the drop: the same decision as without the guard.
      np.testing.assert_array_equal(out.action, free_out.action)
      assert bool(out.departed) and not bool(out.guard.fallen)
    else:  # The drop and after: the actor prior's own sequence.
      np.testing.assert_array_equal(out.sequence, seq)
      assert bool(out.guard.fallen) and not bool(out.departed)
      assert CANDIDATE_KINDS[int(out.kind)] == 'actor_prior'
  assert float(guard.peak) == pytest.approx(float(free_guard.peak))


def test_advance_guard_falls_at_the_drop_and_stays():
  from ld_mpc_jax.plan.planner import advance_guard, initial_guard
  g = initial_guard()
  for score, fallen in [(-50.0, False), (-40.0, False), (-43.0, False), (-45.0, True),
                        (-10.0, True)]:  # Negative values: the drop is relative to |peak|.
    g = advance_guard(g, jnp.float32(score), 0.1, -np.inf)
    assert bool(g.fallen) == fallen
  assert float(g.peak) == -10.0
  g = initial_guard()  # Armed only above the floor: a peak of 100 is not, 300 is.
  for score, fallen in [(100.0, False), (50.0, False), (300.0, False), (260.0, True)]:
    g = advance_guard(g, jnp.float32(score), 0.1, 200.0)
    assert bool(g.fallen) == fallen
  g = initial_guard()
  for score in [100.0, 1.0]:
    g = advance_guard(g, jnp.float32(score), 0.0)
  assert not bool(g.fallen)


def test_batch_policy_carries_the_guard_between_decisions(smoke_config, smoke_params):
  from ld_mpc_jax.plan import agent
  c = safe_config(smoke_config, 0.0)
  c.plan.fallback_drop, c.plan.num_prior_candidates = 0.5, 1
  act = agent.make_batch_act(ActSettings.from_config(c), 'plan')
  obs = jnp.asarray(np.random.default_rng(0).uniform(-1, 1, (3, 39)), jnp.float32)
  keys = agent.episode_keys(0, [1, 2, 3])
  active = jnp.ones(3, bool)
  _, carry, _ = act(smoke_params, obs, keys, 0, None, active)
  sequence, guard = carry
  assert sequence.shape == (3, c.horizon, c.action_dim) and guard.peak.shape == (3,)
  assert np.all(np.isfinite(np.asarray(guard.peak))) and not np.any(np.asarray(guard.fallen))
  _, (_, guard2), info = act(smoke_params, obs, keys, 1, carry, active)
  assert np.all(np.asarray(guard2.peak) >= np.asarray(guard.peak))
  assert np.array_equal(np.asarray(info)[:, 3], np.asarray(guard2.fallen).astype(int))
  high = guard.replace(peak=jnp.full(3, 1e9, jnp.float32))
  _, (_, fell), info = act(smoke_params, obs, keys, 2, (sequence, high), active)
  info = np.asarray(info)  # A value far below its peak: the actor prior acts, and info says so.
  assert np.all(np.asarray(fell.fallen)) and np.all(info[:, 3] == 1) and np.all(info[:, 2] == 0)


def test_fallback_settings_fail_in_one_line(smoke_config):
  c = smoke_config
  c.plan.fallback_drop = 1.5
  with pytest.raises(ValueError, match='fallback_drop must be in'):
    make_plan(c)


def test_first_action_spread_is_the_mean_std_of_first_actions():
  actions = jnp.zeros((4, 3, 2)).at[:, 0, 0].set(jnp.array([-1.0, 1.0, -1.0, 1.0]))
  actions = actions.at[:, 1:].set(5.0)  # Later steps do not count.
  assert float(search.first_action_spread(actions)) == pytest.approx(0.5)  # (1 + 0) / 2.
  mask = jnp.array([True, False, True, False])  # Two equal first actions: no spread.
  assert float(search.first_action_spread(actions, mask)) == 0.0
  assert float(search.first_action_spread(actions, jnp.zeros(4, bool))) == -1.0  # None.
