"""The learned exploration value (ld_mpc_jax.model.novelty): its reward is the members' spread,
high where they were not fitted; its value learns the window's novelty returns; its loss term,
its bonus in the acting planner's J, its settings and old configs."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from ld_mpc_jax import validate_config
from ld_mpc_jax.configs import door_open_online
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.learn import losses
from ld_mpc_jax.online import schedule
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.model import models, novelty, objective
from ld_mpc_jax.ops import legacy
from ld_mpc_jax.ops.numerics import window_returns
from ld_mpc_jax.plan import planner
from ld_mpc_jax.model.settings import LossSettings, ModelSettings, PlanSettings


def acting_plan(config):
  """The acting planner's settings of `config` (OnlineSettings.acting_plan)."""
  return OnlineSettings.from_config(config).acting_plan(PlanSettings.from_config(config))


def acting_schedule(config, learn_start):
  return schedule.ActingSchedule(OnlineSettings.from_config(config), learn_start)

ON = {'loss.w_novelty': 1.0}
D, A = 6, 2


def _fit(net, params, z, action, steps=300, lr=3e-3):
  opt = optax.adam(lr)
  state = opt.init(params)

  @jax.jit
  def step(params, state):
    g = jax.grad(lambda p: novelty.loss(net, p, z, action, 0.9))(params)
    updates, state = opt.update(g, state, params)
    return optax.apply_updates(params, updates), state

  for _ in range(steps):
    params, state = step(params, state)
  return params


def _toy():
  """Windows of a known linear system near the origin: z_{t+1} = 0.9 z_t + B a_t."""
  rng = np.random.default_rng(0)
  b = rng.normal(size=(A, D)) * 0.3
  z0 = rng.normal(size=(64, D)) * 0.3
  action = rng.uniform(-1, 1, (64, 4, A))
  zs = [z0]
  for t in range(4):
    zs.append(0.9 * zs[-1] + action[:, t] @ b)
  return jnp.asarray(np.stack(zs, 1), jnp.float32), jnp.asarray(action, jnp.float32)


def test_the_reward_is_zero_where_members_agree_and_the_members_spread_where_they_were_not_fitted():
  net = novelty.Novelty(5, (32, 32), D)
  z, action = _toy()
  params = {'novelty': novelty.init(net, jax.random.key(0), D, A)}
  same = jax.tree_util.tree_map(lambda x: x, params)
  for e in range(1, 5):  # Every member a copy of member 0: no spread anywhere.
    same['novelty'][f'member_{e}'] = params['novelty']['member_0']
  assert np.all(np.asarray(novelty.reward(net, same, z[:, :-1], action)) == 0.0)
  fitted = _fit(net, params, z, action)
  assert float(novelty.loss(net, fitted, z, action, 0.9)) < float(
      novelty.loss(net, params, z, action, 0.9)) / 5
  seen = np.asarray(novelty.reward(net, fitted, z[:, :-1], action)).mean()
  far = jnp.asarray(np.random.default_rng(1).normal(size=(64, 4, D)) * 3.0, jnp.float32)
  unseen = np.asarray(novelty.reward(net, fitted, far, action)).mean()
  assert unseen > 10 * seen, (unseen, seen)


def test_the_loss_is_the_members_error_plus_the_values_error_against_window_returns():
  net = novelty.Novelty(3, (16,), D)
  z, action = _toy()
  params = {'novelty': novelty.init(net, jax.random.key(1), D, A)}
  preds = net.apply({'params': params['novelty']}, z[:, :-1], action)
  members = np.mean((np.asarray(preds) - np.asarray(z[:, 1:])[None]) ** 2)
  r = np.asarray(preds).var(axis=0).mean(-1)  # [B, T]
  v = lambda x: np.asarray(novelty.value(net, params, x))
  returns = np.asarray(window_returns(jnp.asarray(r), jnp.asarray(v(z[:, -1])), 0.9))
  expected = members + np.mean((v(z[:, :-1]) - returns) ** 2)
  np.testing.assert_allclose(float(novelty.loss(net, params, z, action, 0.9)), expected,
                             rtol=1e-4)


def test_the_bonus_is_scaled_to_mean_one_and_is_zero_without_novelty():
  net = novelty.Novelty(3, (16,), D)
  params = {'novelty': novelty.init(net, jax.random.key(2), D, A)}
  rng = np.random.default_rng(3)
  latents = jnp.asarray(rng.normal(size=(7, 4, D)), jnp.float32)
  actions = jnp.asarray(rng.uniform(-1, 1, (7, 3, A)), jnp.float32)
  n = np.asarray(novelty.bonus(net, params, latents, actions, 0.9))
  assert n.shape == (7,) and np.all(n >= 0) and n.mean() == pytest.approx(1.0, rel=1e-5)
  assert n.std() > 0
  zero = jax.tree_util.tree_map(jnp.zeros_like, params)  # Members agree, V_nov = 0.
  assert np.all(np.asarray(novelty.bonus(net, zero, latents, actions, 0.9)) == 0.0)


def test_obs_targets_are_each_coordinates_change_in_units_of_its_batch_spread():
  rng = np.random.default_rng(4)
  obs = rng.normal(size=(8, 5, 3)).astype(np.float32)
  obs[..., 1] *= 100.0  # A coordinate on another scale is in the same units.
  obs[..., 2] = 0.5  # One that never moves: its targets are 0.
  obs[3, 2:, 2] = 0.51  # ... until it moves once, by 1 cm: then large where it did.
  t = np.asarray(novelty.obs_targets(jnp.asarray(obs)))
  change = np.diff(obs, axis=1)
  expected = change / (change.std(axis=(0, 1)) + novelty.OBS_SCALE_FLOOR)
  np.testing.assert_allclose(t, expected, rtol=1e-4, atol=1e-6)
  assert t.shape == (8, 4, 3)
  assert t[..., 0].std() == pytest.approx(t[..., 1].std(), rel=0.01)
  assert abs(t[3, 1, 2]) > 3 and np.count_nonzero(t[..., 2]) == 1
  assert np.all(np.asarray(novelty.obs_targets(jnp.full((2, 3, 4), 7.0))) == 0.0)
  net = novelty.Novelty(2, (8,), 3, 'obs')
  z, action = _toy()
  params = {'novelty': novelty.init(net, jax.random.key(0), D, A)}
  window_obs = jnp.asarray(rng.normal(size=(64, 5, 3)), jnp.float32)  # The toy's windows.
  assert np.isfinite(float(novelty.loss(net, params, z, action, 0.9, window_obs)))
  with pytest.raises(ValueError, match="target 'obs' need the window's observations"):
    novelty.loss(net, params, z, action, 0.9)
  c = door_open_online.get_config('smoke')
  c.model.novelty_target = 'observation'
  with pytest.raises(ValueError, match="novelty_target must be 'latent' or 'obs'"):
    validate_config(c)


@pytest.mark.parametrize('target', ['latent', 'obs'])
def test_the_model_and_its_loss_have_the_term_only_when_on(smoke_config, target):
  c = with_overrides(smoke_config, dict(ON, **{'model.novelty_target': target}))
  params = models.init_params(c, jax.random.key(0))
  plain = models.init_params(smoke_config, jax.random.key(0))
  assert 'novelty' in params and 'novelty' not in plain
  for name in plain:  # Its own key: the other networks start as without it.
    jax.tree_util.tree_map(np.testing.assert_array_equal, params[name], plain[name])
  rng = np.random.default_rng(0)
  h = c.horizon
  batch = {'obs': jnp.asarray(rng.normal(size=(2, h + 2, 39)), jnp.float32),
           'action': jnp.asarray(rng.uniform(-1, 1, (2, h + 1, 4)), jnp.float32),
           'reward': jnp.zeros((2, h + 1), jnp.float32)}
  nets = models.build_networks(ModelSettings.from_config(c))
  _, metrics = jax.jit(losses.make_loss_fn(ModelSettings.from_config(c),
      LossSettings.from_config(c), nets))(params, params, batch, jax.random.key(1))
  z = models.encode(params, batch['obs'])
  obs = batch['obs']  # Read only by members of target 'obs'.
  preds = nets.novelty.apply({'params': params['novelty']}, z[:, :-1], batch['action'])
  assert preds.shape[-1] == (c.obs_dim if target == 'obs' else c.model.latent_dim)
  expected = novelty.loss(nets.novelty, params, z, batch['action'], c.gamma, obs)
  np.testing.assert_allclose(metrics['loss_novelty'], expected, rtol=1e-5)
  assert ('novelty', 'w_novelty') in losses.WEIGHTS  # So the total counts it, weighted.
  # It reads the latent, it does not shape it: no gradient reaches the latents from its loss;
  # its own parameters get one.
  loss = lambda p, z_: novelty.loss(nets.novelty, p, z_, batch['action'], c.gamma, obs)
  g_params, g_z = jax.grad(loss, argnums=(0, 1))(params, z)
  assert np.all(np.asarray(g_z) == 0.0)
  assert float(jnp.abs(g_params['novelty']['value']['dense_0']['kernel']).max()) > 0


def _intrinsic(novelty_weight):
  return objective.Intrinsic(pessimism=jnp.float32(0.0), disagreement=jnp.float32(0.0),
                             novelty=jnp.float32(novelty_weight))


def test_the_acting_plan_adds_the_weighted_bonus_and_evaluation_does_not(smoke_config):
  c = with_overrides(smoke_config, ON)
  params = models.init_params(c, jax.random.key(0))
  z = models.encode(params, np.ones(c.obs_dim, np.float32))
  plan, key = planner.make_plan(c), jax.random.key(3)
  plain = plan(params, z, key)
  off = plan(params, z, key, None, 0.0, None, _intrinsic(0.0))
  np.testing.assert_array_equal(off.scores, plain.scores)
  np.testing.assert_array_equal(off.action, plain.action)
  on = plan(params, z, key, None, 0.0, None, _intrinsic(3.0))
  gain = np.asarray(on.scores) - np.asarray(plain.scores)
  assert gain.mean() == pytest.approx(3.0, rel=1e-3)  # 3 x a bonus of mean 1.
  assert gain.std() > 0


def test_the_weight_is_annealed_and_validated():
  c = door_open_online.get_config('smoke')
  c.loss.w_novelty = 1.0
  c.online.act_schedule, c.online.act_novelty, c.online.act_novelty_end = 'linear', 2.0, 0.0
  c.online.env_steps = 1000
  schedule = acting_schedule(c, 0)
  assert schedule.novelty(0) == 2.0
  assert schedule.novelty(500) == pytest.approx(1.0)
  assert float(schedule.intrinsic(1000).novelty) == 0.0
  validate_config(c)
  c.loss.w_novelty = 0.0
  with pytest.raises(ValueError, match='needs the learned exploration value'):
    validate_config(c)
  c.loss.w_novelty, c.online.act_novelty_end = 1.0, -1.0
  with pytest.raises(ValueError, match='must be >= 0'):
    validate_config(c)


def test_a_version_2_config_gets_the_fields_off():
  c = door_open_online.get_config('smoke')
  c.version = 2
  del c.loss['w_novelty'], c.model['novelty_members'], c.model['novelty_target']
  del c.online['act_novelty'], c.online['act_novelty_end']
  from ld_mpc_jax.learn import checkpointing
  c = checkpointing.migrate_config(c.to_dict())  # As on load.
  assert (c.version, c.loss.w_novelty, c.online.act_novelty, c.online.act_novelty_end) == (
      legacy.CONFIG_VERSION, 0.0, 0.0, 0.0)
  assert c.model.novelty_target == 'latent' and not c.model.novelty_target == 'obs'
  assert not ModelSettings.from_config(c).novelty
