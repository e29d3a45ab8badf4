"""ld_mpc_jax.model.objective: the members of J combined (mean - pessimism x std), J against the
discounted rewards and terminal values composed by hand, the causality of its rewards, and the
value head's loss, against hand-computed values."""

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.model import objective
from ld_mpc_jax.model.critics import Critics
from ld_mpc_jax.model.models import build_networks
from ld_mpc_jax.ops.numerics import two_hot_decode
from ld_mpc_jax.model.settings import ModelSettings


def test_combine_is_mean_less_pessimism_times_std():
  ens = jnp.array([[1.0, 2.0], [3.0, 2.0]])  # 2 members x 2 states
  np.testing.assert_allclose(objective.combine(ens, 0.5), [2.0 - 0.5, 2.0], rtol=1e-6)
  np.testing.assert_allclose(objective.combine(ens, -1.0), [3.0, 2.0], rtol=1e-6)  # Optimism.
  # One member: its own scores whatever the pessimism.
  np.testing.assert_allclose(objective.combine(jnp.array([[4.0, -1.0]]), 3.0), [4.0, -1.0])


def test_as_members_gives_scores_a_member_axis():
  scores = jnp.arange(5.0)
  np.testing.assert_array_equal(objective.as_members(scores), [[0.0, 1.0, 2.0, 3.0, 4.0]])
  members = jnp.arange(15.0).reshape(3, 5)
  np.testing.assert_array_equal(objective.as_members(members), members)


def _parts(config, params):
  """(member scores, score at pessimism 0.5, rewards [K, H], V_m(z_H) [M, K]) for K = 3 random
  latents and actions, each with its last action flipped too (rows 3-5): one jitted program."""
  m = ModelSettings.from_config(config)
  nets = build_networks(m)
  members = objective.make_member_scores(m, nets, config.plan.progress_weight)
  score = objective.make_score(m, nets, 0.5, config.plan.progress_weight)
  k, h, d, a = 3, config.horizon, config.model.latent_dim, config.action_dim
  latents = jax.random.normal(jax.random.key(1), (k, h + 1, d))
  actions = jax.random.uniform(jax.random.key(2), (k, h, a), minval=-1, maxval=1)
  latents = jnp.concatenate([latents, latents])
  actions = jnp.concatenate([actions, actions.at[:, -1].set(-actions[:, -1])])

  @jax.jit
  def parts(params):
    r_logits, _ = nets.objective.apply({'params': params['objective']}, latents, actions)
    rewards = two_hot_decode(r_logits, config.model.vmin, config.model.vmax)
    values = nets.critics.apply({'params': params['critics']}, latents[:, -1],
                                method=Critics.value)
    return (members(params, latents, actions), score(params, latents, actions), rewards,
            config.critic.value_scale * values)

  return [np.asarray(x, np.float64) for x in parts(params)]


def test_member_scores_are_discounted_rewards_plus_each_terminal_value(smoke_config,
                                                                        smoke_params):
  """J_m = sum_i gamma^i r_i + gamma^H V_m(z_H) member by member, and J = mean - 0.5 std."""
  members, score, rewards, values = _parts(smoke_config, smoke_params)
  gamma, h = smoke_config.gamma, smoke_config.horizon
  assert members.shape == values.shape == (smoke_config.critic.num_values, 6)
  by_hand = sum(gamma ** i * rewards[:, i] for i in range(h))[None] + gamma ** h * values
  np.testing.assert_allclose(members, by_hand, rtol=1e-4, atol=1e-4)
  np.testing.assert_allclose(score, by_hand.mean(0) - 0.5 * by_hand.std(0), rtol=1e-4, atol=1e-4)
  assert np.ptp(members, axis=0).min() > 0  # The members disagree: the pessimism matters.


def test_a_later_action_changes_only_its_own_reward(smoke_config, smoke_params):
  """The causal mask: flipping the last action a_{H-1} leaves every earlier reward as it was,
  and J moves by exactly gamma^(H-1) times the change of r_{H-1} (V_m sees z_H alone)."""
  members, _, rewards, _ = _parts(smoke_config, smoke_params)
  gamma, h = smoke_config.gamma, smoke_config.horizon
  before, after = rewards[:3], rewards[3:]
  np.testing.assert_allclose(after[:, :-1], before[:, :-1], rtol=1e-5, atol=1e-5)
  assert np.abs(after[:, -1] - before[:, -1]).min() > 1e-4  # The last reward does change.
  np.testing.assert_allclose(members[:, 3:] - members[:, :3],
                             np.broadcast_to(gamma ** (h - 1) * (after[:, -1] - before[:, -1]),
                                             (members.shape[0], 3)), rtol=1e-4, atol=1e-4)


def test_value_head_loss_hand_computed():
  # expm1(0.25) two-hots to 0.75 on bin 2 and 0.25 on bin 3.
  probs = jnp.array([0.1, 0.1, 0.5, 0.2, 0.1])
  got = objective.value_head_loss(jnp.log(probs)[None], jnp.array([np.expm1(0.25)]), 5, -2.0,
                                  2.0)
  np.testing.assert_allclose(got, -(0.75 * np.log(0.5) + 0.25 * np.log(0.2)), rtol=1e-5)
