"""plan(): shapes, bounds, determinism, no recompilation, argmax selection, prior mixing, which
kind of candidate won, J over several dynamics draws."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax import encode, init_params, make_plan, validate_config
from ld_mpc_jax.model import models
from ld_mpc_jax.plan import planner
from ld_mpc_jax.model.models import build_networks
from ld_mpc_jax.model.settings import ModelSettings


@pytest.fixture
def z(smoke_params):
  return encode(smoke_params, np.linspace(-1, 1, 39).astype(np.float32))


def test_plan_shapes_and_bounds(smoke_config, smoke_params, z):
  c = smoke_config
  out = make_plan(c)(smoke_params, z, jax.random.key(0))
  k, h, a = c.plan.num_candidates, c.horizon, c.action_dim
  assert out.action.shape == (a,) and out.sequence.shape == (h, a)
  assert out.scores.shape == (k,) and out.candidates.shape == (k, h, a)
  assert bool(jnp.all(jnp.abs(out.action) <= 1.0))
  assert bool(jnp.all(jnp.abs(out.candidates) <= 1.0))
  assert bool(jnp.all(jnp.isfinite(out.scores)))
  assert int(out.index) == int(jnp.argmax(out.scores))
  np.testing.assert_array_equal(out.sequence, out.candidates[out.index])


def test_plan_same_key_same_action_and_no_recompile(smoke_config, smoke_params, z):
  plan = make_plan(smoke_config)
  a = plan(smoke_params, z, jax.random.key(7))
  traced = plan._cache_size()  # Other tests of this config share the planner (build_cache).
  b = plan(smoke_params, z, jax.random.key(7))
  c = plan(smoke_params, z + 0.1, jax.random.key(8))
  np.testing.assert_array_equal(a.action, b.action)
  np.testing.assert_array_equal(a.scores, b.scores)
  assert not np.array_equal(a.candidates, c.candidates)
  assert plan._cache_size() == traced >= 1


def test_plan_returns_argmax_of_hand_made_objective(smoke_config, smoke_params, z):
  smoke_config.plan.num_candidates = 16
  # J = second coordinate of the first action: the planner must pick the largest one.
  score_fn = lambda params, latents, actions: actions[:, 0, 1]
  out = make_plan(smoke_config, score_fn=score_fn)(smoke_params, z, jax.random.key(3))
  best = int(np.argmax(np.asarray(out.candidates[:, 0, 1])))
  assert int(out.index) == best
  np.testing.assert_allclose(out.action, out.candidates[best, 0])
  np.testing.assert_allclose(out.scores, out.candidates[:, 0, 1])


def test_plan_scores_use_rolled_out_latents(smoke_config, smoke_params, z):
  """A score of the final latent sees the dynamics rollout, not just the first latent."""
  smoke_config.plan.num_candidates = 8
  seen = {}
  def score_fn(params, latents, actions):
    seen['shape'] = latents.shape
    return -jnp.sum((latents[:, -1] - latents[:, 0]) ** 2, axis=-1)
  out = make_plan(smoke_config, score_fn=score_fn)(smoke_params, z, jax.random.key(3))
  c = smoke_config
  assert seen['shape'] == (8, c.horizon + 1, c.model.latent_dim)
  assert len(set(np.round(np.asarray(out.scores), 5))) > 1  # Rollouts differ per candidate.


def test_actor_prior_candidates_follow_the_actor(smoke_config, smoke_params, z):
  smoke_config.plan.num_candidates = 6
  smoke_config.plan.num_prior_candidates = 2
  out = make_plan(smoke_config)(smoke_params, z, jax.random.key(0))
  nets = build_networks(ModelSettings.from_config(smoke_config))
  a_pi = nets.actor.apply({'params': smoke_params['actor']}, z)
  np.testing.assert_allclose(out.candidates[-1, 0], a_pi, rtol=1e-5, atol=1e-6)
  np.testing.assert_allclose(out.candidates[-2, 0], a_pi, rtol=1e-5, atol=1e-6)
  assert not np.allclose(out.candidates[0, 0], a_pi)


def test_plan_rejects_wrong_latent(smoke_config, smoke_params):
  plan = make_plan(smoke_config)
  with pytest.raises(ValueError, match='latent of shape'):
    plan(smoke_params, jnp.zeros(smoke_config.model.latent_dim + 1), jax.random.key(0))
  with pytest.raises(ValueError, match='latent of shape'):
    plan(smoke_params, jnp.zeros((2, smoke_config.model.latent_dim)), jax.random.key(0))


@pytest.mark.parametrize('field,value', [
    ('plan.num_candidates', 0), ('horizon', 0), ('plan.action_steps', -1),
    ('plan.dynamics_steps', 0), ('train.batch_size', 0), ('model.num_heads', 3),
    ('plan.num_prior_candidates', 5), ('plan.action_eta', 2.0), ('gamma', 1.5)])
def test_bad_config_values_name_the_field(smoke_config, field, value):
  node = smoke_config
  *parents, leaf = field.split('.')
  for p in parents:
    node = node[p]
  node[leaf] = value
  with pytest.raises(ValueError, match=leaf):
    validate_config(smoke_config)
  with pytest.raises(ValueError, match=leaf):
    make_plan(smoke_config)
  if field in ('plan.num_prior_candidates', 'plan.action_eta'):  # The search's own checks
    init_params(smoke_config, jax.random.key(0))  # (plan.search.validate_plan): no network's.
    return
  with pytest.raises(ValueError, match=leaf):
    init_params(smoke_config, jax.random.key(0))


@pytest.mark.parametrize('num_prior', [0, 2])  # 2: as the warm-started fast planner.
def test_warm_start_is_deterministic_valid_and_stays_near_the_previous_plan(
    smoke_config, smoke_params, z, num_prior):
  smoke_config.plan.num_candidates = 8
  smoke_config.plan.num_prior_candidates = num_prior
  smoke_config.plan.warm_start_steps = 2
  smoke_config.plan.warm_start_t = 0.05  # Little noise: candidates stay near the old plan.
  # With eps-prediction an untrained denoiser changes x_t by only O(sigma_t), so the result
  # must stay near the (shifted) warm start; an x0-predicting random network would not.
  smoke_config.diffusion.prediction = 'eps'
  plan = make_plan(smoke_config)
  h, a = smoke_config.horizon, smoke_config.action_dim
  prev = jnp.tile(jnp.linspace(-0.5, 0.5, h)[:, None], (1, a))
  first = plan(smoke_params, z, jax.random.key(0), prev)
  again = plan(smoke_params, z, jax.random.key(0), prev)
  np.testing.assert_array_equal(first.action, again.action)
  np.testing.assert_array_equal(first.candidates, again.candidates)
  assert bool(jnp.all(jnp.abs(first.candidates) <= 1.0))
  # The shifted previous plan is [prev[1], ..., prev[H-1], prev[H-1]].
  shifted = jnp.concatenate([prev[1:], prev[-1:]])
  cold = plan(smoke_params, z, jax.random.key(0))
  n = smoke_config.plan.num_candidates - num_prior  # Proposals; the rest follow the actor.
  warm_err = float(jnp.mean(jnp.abs(first.candidates[:n] - shifted)))
  cold_err = float(jnp.mean(jnp.abs(cold.candidates[:n] - shifted)))
  assert warm_err < 0.5 * cold_err, (warm_err, cold_err)
  with pytest.raises(ValueError, match='prev_sequence'):
    plan(smoke_params, z, jax.random.key(0), prev[:-1])


@pytest.mark.parametrize('overrides', [
    # Benchmark variant `fast` (the :cpu preset without warm start): DDIM 4 x 1 + actor.
    {'action_steps': 4, 'dynamics_steps': 1, 'action_eta': 0.0, 'dynamics_eta': 0.0,
     'num_prior_candidates': 2},
    {'action_steps': 8, 'dynamics_steps': 2, 'action_eta': 0.0, 'dynamics_eta': 0.0},
    {'action_steps': 1, 'dynamics_steps': 1, 'action_eta': 0.0, 'dynamics_eta': 0.0,
     'num_candidates': 2},
])
def test_fast_variants_return_valid_deterministic_actions(smoke_config, smoke_params, z,
                                                          overrides):
  for field, value in overrides.items():
    smoke_config.plan[field] = value
  plan = make_plan(smoke_config)
  out = plan(smoke_params, z, jax.random.key(7))
  again = plan(smoke_params, z, jax.random.key(7))
  np.testing.assert_array_equal(out.candidates, again.candidates)
  k = smoke_config.plan.num_candidates
  assert out.candidates.shape == (k, smoke_config.horizon, smoke_config.action_dim)
  assert bool(jnp.all(jnp.abs(out.candidates) <= 1.0))
  assert bool(jnp.all(jnp.isfinite(out.scores)))
  np.testing.assert_array_equal(out.action, out.candidates[int(jnp.argmax(out.scores)), 0])


def test_plan_reports_which_kind_of_candidate_won(smoke_config, smoke_params):
  config = with_overrides(smoke_config, {'plan.num_candidates': 4,
                                         'plan.num_prior_candidates': 2})
  z = models.encode(smoke_params, np.zeros(config.obs_dim))
  last = planner.make_plan(config, lambda p, lat, act: jnp.arange(act.shape[0], dtype=float))
  first = planner.make_plan(config, lambda p, lat, act: -jnp.arange(act.shape[0], dtype=float))
  key = jax.random.key(0)
  assert planner.CANDIDATE_KINDS[int(last(smoke_params, z, key).kind)] == 'actor_prior'
  assert planner.CANDIDATE_KINDS[int(first(smoke_params, z, key).kind)] == 'proposal'


def test_actor_prior_candidates_are_diverse_and_keep_the_actor(smoke_config, smoke_params):
  config = with_overrides(smoke_config, {'plan.num_candidates': 4, 'plan.num_prior_candidates': 3,
                                         'plan.prior_noise_std': 0.3})
  nets = models.build_networks(ModelSettings.from_config(config))
  z = models.encode(smoke_params, np.ones(config.obs_dim))
  out = planner.make_plan(config)(smoke_params, z, jax.random.key(0))
  prior = out.candidates[1:]  # [3, H, A]
  actor = nets.actor.apply({'params': smoke_params['actor']}, z)
  np.testing.assert_allclose(prior[0, 0], actor, rtol=1e-5, atol=1e-6)  # The actor's own.
  assert float(jnp.abs(prior[1, 0] - prior[2, 0]).max()) > 1e-3  # The others differ.


def test_dynamics_draws_average_the_scores(smoke_config, smoke_params):
  """With 2 draws and the proposal fixed by the key, J is the mean over two rollouts."""
  one = planner.make_plan(smoke_config)
  two = planner.make_plan(with_overrides(smoke_config, {'plan.dynamics_draws': 2}))
  z = models.encode(smoke_params, np.ones(smoke_config.obs_dim))
  a, b = one(smoke_params, z, jax.random.key(0)), two(smoke_params, z, jax.random.key(0))
  np.testing.assert_allclose(a.candidates, b.candidates)
  assert float(jnp.abs(a.scores - b.scores).max()) > 1e-6
