"""Environment-loop policies: planner (cold and warm), actor prior, proposal alone."""

import numpy as np
import pytest

import jax

from ld_mpc_jax.plan.agent import make_act, make_policy
from ld_mpc_jax.model.models import build_networks, encode
from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.plan.modes import ActSettings


@pytest.mark.parametrize('mode', ['plan', 'actor', 'proposal'])
def test_policies_follow_their_key_schedule(smoke_config, smoke_params, mode):
  """A policy's actions are a function of its seed and the decision's index: the same under the
  same seed, others under another seed and at the next decision of the same observation; the
  actor prior's mode needs no key and is the same under every seed."""
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  runs = []
  for seed in (0, 0, 1):
    policy, _ = make_policy(ActSettings.from_config(smoke_config), smoke_params, mode, seed=seed)
    runs.append(np.stack([policy(obs) for _ in range(3)]))
  assert runs[0].shape == (3, smoke_config.action_dim) and np.all(np.isfinite(runs[0]))
  np.testing.assert_array_equal(runs[0], runs[1])
  if mode == 'actor':
    np.testing.assert_array_equal(runs[0], runs[2])
    np.testing.assert_array_equal(runs[0][1:], runs[0][:1].repeat(2, axis=0))
  else:
    assert np.abs(runs[0] - runs[2]).max(axis=-1).min() > 1e-3  # Each decision: another key.
    assert np.abs(runs[0][1:] - runs[0][:1]).max(axis=-1).min() > 1e-3  # fold_in(key, t).


def test_plan_policy_acts_with_the_planners_action(smoke_config, smoke_params):
  """Decision t of the plan policy is the planner's action on the encoded observation under
  fold_in(key(seed), t)."""
  from ld_mpc_jax.plan.planner import make_plan
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  policy, _ = make_policy(ActSettings.from_config(smoke_config), smoke_params, 'plan', seed=5)
  actions = [policy(obs) for _ in range(2)]
  plan = jax.jit(make_plan(smoke_config))
  z = encode(smoke_params, obs)
  for t, action in enumerate(actions):
    expected = plan(smoke_params, z, jax.random.fold_in(jax.random.key(5), t)).action
    np.testing.assert_allclose(action, expected, rtol=1e-5, atol=1e-6)


def test_actor_policy_is_the_actor_prior(smoke_config, smoke_params):
  policy, _ = make_policy(ActSettings.from_config(smoke_config), smoke_params, 'actor')
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  nets = build_networks(ModelSettings.from_config(smoke_config))
  expected = nets.actor.apply({'params': smoke_params['actor']}, encode(smoke_params, obs))
  np.testing.assert_allclose(policy(obs), expected, rtol=1e-5, atol=1e-6)


def test_actor_acting_noise_only_when_asked(smoke_config, smoke_params):
  """The actor prior acting online (`online.act_mode='actor'`) gets the executed-action noise;
  at noise 0 it is exactly the actor prior."""
  act = make_act(ActSettings.from_config(smoke_config), 'actor')
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  key = jax.random.key(0)
  plain = np.asarray(act(smoke_params, obs, key, 0, None, 0.0)[0])
  policy, _ = make_policy(ActSettings.from_config(smoke_config), smoke_params, 'actor')
  np.testing.assert_allclose(plain, policy(obs), rtol=1e-5, atol=1e-6)
  noisy = np.stack([np.asarray(act(smoke_params, obs, key, t, None, 0.3)[0]) for t in range(64)])
  assert np.all(np.abs(noisy) <= 1.0)
  inside = np.abs(plain) < 0.9  # Away from the clip, the spread is the asked std.
  assert 0.2 < np.std(noisy[:, inside] - plain[inside]) < 0.4


def test_proposal_gets_the_evaluation_action_noise_only_when_asked(smoke_config, smoke_params):
  """`eval.action_noise` perturbs the proposal's executed action as the actor prior's; at 0 it
  is exactly the proposal's sample."""
  act = make_act(ActSettings.from_config(smoke_config), 'proposal')
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  key = jax.random.key(0)
  plain = np.stack([np.asarray(act(smoke_params, obs, key, t, None, 0.0)[0]) for t in range(64)])
  again = np.stack([np.asarray(act(smoke_params, obs, key, t, None, 0.0)[0]) for t in range(2)])
  np.testing.assert_array_equal(plain[:2], again)
  noisy = np.stack([np.asarray(act(smoke_params, obs, key, t, None, 0.3)[0]) for t in range(64)])
  assert np.all(np.abs(noisy) <= 1.0)
  inside = np.abs(plain) < 0.9
  assert 0.2 < np.std((noisy - plain)[inside]) < 0.4


def test_warm_started_policy_is_reproducible(smoke_config, smoke_params):
  smoke_config.plan.warm_start_steps = 1
  obs = [np.full(39, v) for v in (0.1, 0.2, 0.3)]
  runs = []
  for _ in range(2):
    policy, reset = make_policy(ActSettings.from_config(smoke_config), smoke_params, 'plan', seed=3)
    reset()
    runs.append([policy(o) for o in obs])
  np.testing.assert_array_equal(np.stack(runs[0]), np.stack(runs[1]))


@pytest.mark.parametrize('mode,chunk', [('actor', None), ('plan', None), ('plan', 1),
                                        ('plan', 0)])
def test_lockstep_batch_equals_one_at_a_time(smoke_config, smoke_params, mode, chunk):
  """N environments with one jitted call per decision give the episodes of one-at-a-time
  evaluation, for the actor and for the warm-started planner (fixed key schedule)."""
  from ld_mpc_jax.eval import evaluation
  from ld_mpc_jax.plan.agent import BatchAgentPolicy
  smoke_config.plan.warm_start_steps = 1
  episodes = evaluation.seeded_episodes(0, 3)
  policy, reset = make_policy(ActSettings.from_config(smoke_config), smoke_params, mode, seed=2)
  single = evaluation.evaluate(policy, smoke_config.task, episodes=episodes, reset=reset,
                               max_episode_steps=30, progress=False)['records']
  batch_policy = BatchAgentPolicy(ActSettings.from_config(smoke_config), smoke_params, mode,
                                  seed=2, chunk=chunk)
  batched, _ = evaluation.run_episodes(batch_policy, episodes, smoke_config.task, batch_size=3,
                                       max_episode_steps=30, progress=False)
  assert [r['length'] for r in batched] == [r['length'] for r in single]
  assert [r['success'] for r in batched] == [r['success'] for r in single]
  np.testing.assert_allclose([r['return'] for r in batched], [r['return'] for r in single],
                             rtol=1e-6)
  # A different policy seed gives different planner episodes (the keys matter).
  if mode == 'plan':
    batch_policy.seed = 3  # Same compiled function, other keys.
    rec, _ = evaluation.run_episodes(batch_policy, episodes, smoke_config.task, batch_size=3,
                                     max_episode_steps=30, progress=False)
    assert [r['return'] for r in rec] != [r['return'] for r in batched]


def test_mppi_settings_are_checked_by_the_mppi_mode_alone(smoke_config):
  """A config.mppi that MPPI refuses leaves the other modes as they are."""
  from ld_mpc_jax.configs.overrides import with_overrides  # pylint: disable=g-import-not-at-top
  c = with_overrides(smoke_config, {'mppi.num_samples': 16})  # Fewer than its 24 prior ones.
  make_act(ActSettings.from_config(c), 'plan')
  with pytest.raises(ValueError, match='^config.mppi: num_prior must be in'):
    make_act(ActSettings.from_config(c), 'mppi')


@pytest.mark.parametrize('fallback', [0.0, 0.5])
def test_kept_sequences_are_the_planners_and_lead_with_its_action(smoke_config, smoke_params,
                                                                  fallback):
  """keep_sequences: BatchAgentPolicy (batched, and one call per environment) and
  SeedsAgentPolicy leave the planner's chosen sequences [.., H, A], whose first action is the
  executed one (no noise), the same for one seed of several as for that seed alone; with the
  fallback's Guard in the carry as without it."""
  from ld_mpc_jax.plan.agent import BatchAgentPolicy  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.plan.seeds_agent import SeedsAgentPolicy  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs.goals import Episode  # pylint: disable=g-import-not-at-top
  smoke_config.plan.fallback_drop = fallback
  if fallback:  # The fallback gates safe selection, which keeps the actor prior's sequence.
    smoke_config.plan.safe_selection = True
    smoke_config.plan.num_prior_candidates = max(1, smoke_config.plan.num_prior_candidates)
  settings = ActSettings.from_config(smoke_config)
  obs = np.random.default_rng(0).normal(size=(2, 39)).astype(np.float32)
  episodes = [Episode('held_out', i, 0, 10 + i, '', None) for i in range(2)]
  active = np.ones(2, bool)
  kept = []
  for chunk in (None, 0):
    policy = BatchAgentPolicy(settings, smoke_params, 'plan', seed=1, chunk=chunk,
                              keep_sequences=True)
    policy.start(episodes)
    actions = policy(obs, 0, active)
    assert policy.last_sequences.shape == (2, smoke_config.horizon, smoke_config.action_dim)
    np.testing.assert_allclose(policy.last_sequences[:, 0], actions, atol=1e-6)
    kept.append(policy.last_sequences)
  np.testing.assert_allclose(kept[0], kept[1], atol=1e-5)
  stacked = jax.tree_util.tree_map(lambda x: np.stack([x, x]), smoke_params)
  seeds = SeedsAgentPolicy(settings, stacked, 'plan', [1, 2], keep_sequences=True)
  seeds.start([episodes, episodes])
  seeds(np.stack([obs, obs]), 0, active)
  assert seeds.last_sequences.shape == (2, 2, smoke_config.horizon, smoke_config.action_dim)
  np.testing.assert_allclose(seeds.last_sequences[0], kept[0], atol=1e-5)


def test_decide_writes_nothing_on_the_policy_and_chains_its_carry_as_calls_do(smoke_config,
                                                                               smoke_params):
  """An acting wave's decisions (`decide`, ld_mpc_jax.online.seats.run_wave) leave every
  attribute of the policy as it was, and passing each decision's carry to the next gives the
  actions, infos and sequences of the stateful calls; for both batch policies."""
  from ld_mpc_jax.plan.agent import BatchAgentPolicy  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.plan.seeds_agent import SeedsAgentPolicy  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.envs.goals import Episode  # pylint: disable=g-import-not-at-top
  settings = ActSettings.from_config(smoke_config)
  rng = np.random.default_rng(0)
  episodes = [Episode('held_out', i, 0, 10 + i, '', None) for i in range(2)]
  active = np.array([True, False])  # An inactive environment keeps its carry.
  stacked = jax.tree_util.tree_map(lambda x: np.stack([x, x]), smoke_params)
  makers = [(lambda: BatchAgentPolicy(settings, smoke_params, 'plan', seed=1, chunk=chunk,
                                      keep_sequences=True), (2, 39)) for chunk in (None, 0)]
  makers.append((lambda: SeedsAgentPolicy(settings, stacked, 'plan', [1, 2],
                                          keep_sequences=True), (2, 2, 39)))
  for make, shape in makers:
    obs = [rng.normal(size=shape).astype(np.float32) for _ in range(3)]
    eps = episodes if len(shape) == 2 else [episodes, episodes]
    stateful, pure = make(), make()
    stateful.start(eps)
    pure.start(eps)
    before = dict(vars(pure))
    carry, params = None, pure.prepare(stacked if len(shape) == 3 else smoke_params)
    for t, o in enumerate(obs):
      actions, infos, sequences, carry = pure.decide(params, o, t, active, carry)
      np.testing.assert_allclose(actions, stateful(o, t, active), atol=1e-5)
      np.testing.assert_allclose(infos, stateful.last_info, atol=1e-5)
      np.testing.assert_allclose(sequences, stateful.last_sequences, atol=1e-5)
    assert vars(pure).keys() == before.keys()
    assert all(vars(pure)[k] is v for k, v in before.items())
    assert carry is not None and pure.prev is None
