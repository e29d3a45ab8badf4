"""ld_mpc_jax.model.critics: expectile values, AWR weights, TD targets; the terminal value the planner
reads from them, and runs saved before the critics existed."""

import jax
import ml_collections
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.model import critics, models, objective
from ld_mpc_jax.ops import legacy
from ld_mpc_jax.plan import planner
from ld_mpc_jax.ops.numerics import discounted_return, two_hot_decode
from ld_mpc_jax.model.settings import LossSettings, ModelSettings


def test_expectile_loss_hand_computed():
  diff = jnp.array([2.0, -2.0, 0.5, 0.0])
  np.testing.assert_allclose(critics.expectile_loss(diff, 0.9),
                             [0.9 * 4.0, 0.1 * 4.0, 0.9 * 0.25, 0.0], rtol=1e-6)
  # tau = 0.5 is half the squared error.
  np.testing.assert_allclose(critics.expectile_loss(diff, 0.5), 0.5 * diff ** 2, rtol=1e-6)


def test_awr_weights_hand_computed():
  np.testing.assert_allclose(critics.awr_weights(jnp.array([0.0, 1.0, 10.0]), 2.0, 100.0),
                             [1.0, np.exp(2.0), 100.0], rtol=1e-6)


def _toy_values(smoke_config, expectile: float, steps: int = 600):
  """Trains the critics on a toy MDP whose data make the behaviour value mis-rank two actions.

  States (one-hot latents): s0, good, bad, T (absorbing, reward 0). From s0, action 'left'
  leads to good and 'right' to bad, both with reward 0. In good the data hold the expert action
  (reward 10) in 1 of 10 windows and random actions (reward 0) in the others; in bad every
  action earns 3. The behaviour policy's value of good is 1, below bad's 3; the best in-support
  policy gets 10 from good. Q by one-step TD (IQL): the 'window' target would follow the data's
  own action out of good and value 'left' by the behaviour again. Returns (V [4 states],
  Q(s0, left), Q(s0, right)).
  """
  config = with_overrides(smoke_config, {'horizon': 1, 'gamma': 0.9,
                                         'critic.td_target': 'one_step',
                                         'critic.expectile': expectile,
                                         'critic.value_scale': 10.0,
                                         'critic.num_values': 2,
                                         'critic.hidden': (32,)})
  eye = jnp.eye(4)
  s0, good, bad, term = eye
  left, right = jnp.array([1.0, 0, 0, 0]), jnp.array([-1.0, 0, 0, 0])
  expert, rand = jnp.array([0, 1.0, 0, 0]), jnp.array([0, -1.0, 0, 0])
  windows = ([((s0, good, term), (left, expert), (0.0, 10.0))]
             + [((s0, good, term), (left, rand), (0.0, 0.0))] * 9
             + [((s0, bad, term), (right, rand), (0.0, 3.0))] * 10
             + [((term, term, term), (rand, rand), (0.0, 0.0))] * 5)
  z = jnp.stack([jnp.stack(w[0]) for w in windows])  # [B, H+2 = 3, 4]
  action = jnp.stack([jnp.stack(w[1]) for w in windows])  # [B, H+1 = 2, 4]
  reward = jnp.array([w[2] for w in windows])
  net = critics.build_critics(ModelSettings.from_config(config))
  params = {'critics': net.init(jax.random.key(0), z[:, 0], action[:, 0])['params']}
  loss_fn = critics.make_critic_loss(ModelSettings.from_config(config),
      LossSettings.from_config(config), net)
  tx = optax.adam(1e-2)

  @jax.jit
  def step(carry, _):
    params, target, opt = carry
    def total(p):
      losses, _, _ = loss_fn(p, target, z, z, None, action, reward)
      return losses['q'] + losses['v']
    grads = jax.grad(total)(params)
    updates, opt = tx.update(grads, opt, params)
    params = optax.apply_updates(params, updates)
    target = optax.incremental_update(params, target, 0.1)
    return (params, target, opt), None

  (params, _, _), _ = jax.lax.scan(step, (params, params, tx.init(params)), None, length=steps)
  v = objective.make_terminal_value(ModelSettings.from_config(config), net)(params, eye)
  q = 10.0 * net.apply({'params': params['critics']}, jnp.stack([s0, s0]),
                       jnp.stack([left, right]), method=critics.Critics.q_value).mean(0)
  return np.asarray(v), float(q[0]), float(q[1])


def test_expectile_value_ranks_what_the_behaviour_value_misranks(smoke_config):
  v_beh, left_beh, right_beh = _toy_values(smoke_config, 0.5)  # tau = 0.5: the mean return.
  assert v_beh[1] == pytest.approx(1.0, abs=0.4) and v_beh[2] == pytest.approx(3.0, abs=0.4)
  assert left_beh < right_beh  # The behaviour value prefers 'right'.
  v_exp, left_exp, right_exp = _toy_values(smoke_config, 0.9)
  # The 0.9-expectile of {10 w.p. 0.1, 0 w.p. 0.9} is 5: good now beats bad's 3.
  assert v_exp[1] > v_exp[2] + 1.0
  assert left_exp > right_exp
  assert abs(v_exp[3]) < 0.5  # The absorbing state's value stays 0.


def _objective_terminal_part(config, params, latents, actions):
  """J minus its discounted rewards: gamma^H times the terminal value the planner uses."""
  nets = models.build_networks(ModelSettings.from_config(config))
  score = objective.make_score(ModelSettings.from_config(config), nets, config.plan.pessimism,
      config.plan.progress_weight)

  @jax.jit  # One program: operation by operation, the networks compile many small ones.
  def terminal_part(params, latents, actions):
    r_logits, _ = nets.objective.apply({'params': params['objective']}, latents, actions)
    rewards = two_hot_decode(r_logits, config.model.vmin, config.model.vmax)
    return score(params, latents, actions) - discounted_return(rewards, 0.0, config.gamma)

  return terminal_part(params, latents, actions)


@pytest.mark.parametrize('value', ['expectile', 'behaviour'])
def test_terminal_value_cannot_see_the_action_prefix(smoke_config, value):
  config = with_overrides(smoke_config, {'critic.value': value})
  params = models.init_params(config, jax.random.key(0))
  k, h, d, a = 3, config.horizon, config.model.latent_dim, config.action_dim
  latents = jax.random.normal(jax.random.key(1), (k, h + 1, d))
  actions = jax.random.uniform(jax.random.key(2), (k, h, a), minval=-1, maxval=1)
  changed = actions.at[:, 0].set(-actions[:, 0])  # Only a_0 changes; z_H is the same.
  before = _objective_terminal_part(config, params, latents, actions)
  after = _objective_terminal_part(config, params, latents, changed)
  if value == 'expectile':
    np.testing.assert_allclose(before, after, rtol=1e-5, atol=1e-5)
  else:  # The behaviour value is read through the causal transformer, which sees a_0.
    assert float(jnp.max(jnp.abs(before - after))) > 1e-4


def test_legacy_config_keeps_the_behaviour_objective(smoke_config):
  """A run saved before the critic settings existed: no critics, no normalisation, same planner."""
  old = smoke_config.to_dict()
  del old['critic'], old['version']  # Saved before both existed.
  for name in ('normalize_obs', 'normalize_dynamics'):
    del old['model'][name]
  for name in ('pessimism', 'dynamics_draws'):
    del old['plan'][name]
  old = checkpointing.migrate_config(old)  # As on load.
  params = models.init_params(old, jax.random.key(0))
  assert 'critics' not in params and 'obs_mean' not in params['encoder']
  out = planner.make_plan(old)(params, models.encode(params, np.ones(39)), jax.random.key(1))
  assert out.scores.shape == (old.plan.num_candidates,)
  explicit = with_overrides(old, {})
  explicit.critic = ml_collections.ConfigDict(dict(legacy.LEGACY_CRITIC,
                                                   **legacy.V8_FIELDS['critic']))
  assert not models.uses_critics(ModelSettings.from_config(explicit))


def test_policy_td_targets_against_hand_computed_values(smoke_config):
  """critic.td_target 'policy' (TD-MPC2): Q <- r + gamma min_j Q_ema(z', pi(z')), V <- min_j
  Q_ema(z, pi(z)); linear heads, so the targets are computed here by hand."""
  c = smoke_config
  c.horizon, c.gamma = 1, 0.9
  o = c.critic
  o.hidden, o.num_values, o.num_q, o.value_scale, o.td_target = (), 2, 2, 1.0, 'policy'
  d, a_dim = 3, 2
  net = critics.Critics((), 2, 2)
  rng = np.random.default_rng(0)
  z = rng.normal(size=(1, 3, d)).astype(np.float32)  # [B, H+2, D]
  z_ema = z + 0.5
  action = rng.uniform(-1, 1, (1, 2, a_dim)).astype(np.float32)
  reward = np.array([[1.0, 2.0]], np.float32)
  a_pi = np.array([0.3, -0.7], np.float32)
  params = {'critics': net.init(jax.random.key(0), z[:, :2], action)['params']}
  target = {'critics': jax.tree_util.tree_map(lambda x: x * 0.5, params['critics'])}
  policy = lambda p, zz: jnp.broadcast_to(a_pi, zz.shape[:-1] + (a_dim,))
  loss = critics.make_critic_loss(ModelSettings.from_config(c),
      LossSettings.from_config(c), net, policy)
  losses, _, _ = loss(params, target, z, z_ema, None, action, reward)

  def linear(p, head, x):  # Every member of one ensemble: [num, ...].
    k, b = p[head]['heads']['dense_0']['kernel'], p[head]['heads']['dense_0']['bias']
    return np.einsum('...i,nio->n...o', x, np.asarray(k))[..., 0] + np.asarray(b)[:, None, None, 0]

  sa = lambda zz, aa: np.concatenate([zz, np.broadcast_to(aa, zz.shape[:-1] + (a_dim,))], -1)
  q_next = linear(target['critics'], 'q', sa(z_ema[:, 1:], a_pi)).min(0)  # [B, 2]
  q_target = reward + 0.9 * q_next
  q = linear(params['critics'], 'q', sa(z[:, :2], action))
  np.testing.assert_allclose(losses['q'], np.mean((q - q_target) ** 2), rtol=1e-5)
  v_target = linear(target['critics'], 'q', sa(z_ema[:, :2], a_pi)).min(0)
  v = linear(params['critics'], 'v', z[:, :2])
  np.testing.assert_allclose(losses['v'], np.mean((v - v_target) ** 2), rtol=1e-5)
