"""The TD-MPC2 control (`door_open_online.py:tdmpc2_cpu`, issue 100): its pieces against TD-MPC2's
published equations (Hansen et al. 2024; github nicklashansen/tdmpc2), written out here in numpy
(SimNorm, two-hot in symlog space over 101 bins, the Q target r + gamma min of two random target
members at (z', pi(z'))), and a smoke run of the preset, shrunk, end to end."""

import csv
import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, door_open_online
from ld_mpc_jax.learn.losses import make_loss_fn
from ld_mpc_jax.model import critics as critics_lib
from ld_mpc_jax.model.config_checks import check_config
from ld_mpc_jax.model.models import build_networks, encode, init_params
from ld_mpc_jax.model.settings import LossSettings, ModelSettings
from ld_mpc_jax.model.tdmpc2_world import simnorm as world_simnorm
from ld_mpc_jax.ops import numerics


def _np_simnorm(x: np.ndarray, group: int = 8) -> np.ndarray:
  """TD-MPC2's SimNorm: each group of `group` consecutive features -> exp(x_i) / sum_j exp(x_j)."""
  g = x.reshape(x.shape[:-1] + (-1, group)).astype(np.float64)
  e = np.exp(g - g.max(-1, keepdims=True))
  return (e / e.sum(-1, keepdims=True)).reshape(x.shape)


def _np_two_hot(x: float, num_bins: int = 101, vmin: float = -10.0, vmax: float = 10.0):
  """TD-MPC2's math.two_hot: symlog, clamp, split between bin floor((y - vmin) / size) and the next."""
  y = float(np.clip(np.sign(x) * np.log1p(abs(x)), vmin, vmax))
  size = (vmax - vmin) / (num_bins - 1)
  idx = int(np.floor((y - vmin) / size))
  offset = (y - vmin) / size - idx
  out = np.zeros(num_bins)
  out[idx] = 1 - offset
  if idx + 1 < num_bins:
    out[idx + 1] = offset
  return out


def test_simnorm_is_a_softmax_over_each_group_of_eight():
  x = np.random.default_rng(0).normal(size=(3, 64)).astype(np.float32) * 3
  got = np.asarray(numerics.simnorm(jnp.asarray(x)))
  np.testing.assert_allclose(got, _np_simnorm(x), rtol=1e-5, atol=1e-7)
  np.testing.assert_allclose(got.reshape(3, 8, 8).sum(-1), 1.0, rtol=1e-5)
  np.testing.assert_allclose(got, np.asarray(world_simnorm(jnp.asarray(x), 8)), rtol=1e-6)
  # Not a softmax over the whole vector, nor over groups of another size.
  assert not np.allclose(got, _np_simnorm(x, 64), atol=1e-3)
  assert not np.allclose(got, _np_simnorm(x, 4), atol=1e-3)


def _tdmpc2_config(smoke: bool = True):
  c = door_open_online.get_config('tdmpc2_cpu')
  if smoke:
    _shrink(c)
  return c


def test_the_encoder_and_the_mlp_dynamics_end_on_simnorm():
  """latent_norm='simnorm': the latent is SimNorm(LayerNorm(last layer)), each group of 8 on a
  simplex; `encode` (which reads sizes off the parameters) agrees with the network."""
  c = _tdmpc2_config()
  m = ModelSettings.from_config(c)
  nets, params = build_networks(m), init_params(c, jax.random.PRNGKey(0))
  obs = jax.random.normal(jax.random.PRNGKey(1), (5, c.obs_dim))
  z = nets.encoder.apply({'params': params['encoder']}, obs)
  enc = params['encoder']
  h = obs
  for i in range(2):
    h = h @ enc['mlp'][f'dense_{i}']['kernel'] + enc['mlp'][f'dense_{i}']['bias']
    if i == 0:
      mu, var = h.mean(-1, keepdims=True), h.var(-1, keepdims=True)
      h = (h - mu) / jnp.sqrt(var + 1e-6) * enc['mlp']['norm_0']['scale'] + enc['mlp']['norm_0']['bias']
      h = h * jnp.tanh(jax.nn.softplus(h))
  mu, var = h.mean(-1, keepdims=True), h.var(-1, keepdims=True)
  h = (h - mu) / jnp.sqrt(var + 1e-6) * enc['latent_norm']['scale'] + enc['latent_norm']['bias']
  np.testing.assert_allclose(np.asarray(z), _np_simnorm(np.asarray(h)), atol=1e-5)
  np.testing.assert_allclose(np.asarray(encode(params, obs)), np.asarray(z), atol=1e-6)
  a = jax.random.uniform(jax.random.PRNGKey(2), (5, c.action_dim), minval=-1, maxval=1)
  z_next = np.asarray(nets.dynamics.apply({'params': params['dynamics']}, z, a))
  np.testing.assert_allclose(z_next.reshape(5, -1, 8).sum(-1), 1.0, rtol=1e-5)
  assert (z_next > 0).all()


@pytest.mark.parametrize('x', [0.0, 0.37, 1.0, -3.7, 12.5, -250.0, 1234.5, 3e5])
def test_two_hot_matches_tdmpc2_in_symlog_space_over_101_bins(x):
  got = np.asarray(numerics.two_hot(jnp.float32(x), 101, -10.0, 10.0))
  np.testing.assert_allclose(got, _np_two_hot(x), atol=1e-5)
  # Decoding: symexp of the expected bin centre under softmax(logits); the log of a two-hot
  # decodes to x itself (clipped at symexp(10)).
  logits = jnp.log(jnp.asarray(_np_two_hot(x), jnp.float32) + 1e-30)
  centres = np.linspace(-10.0, 10.0, 101)
  y = float(np.sum(_np_two_hot(x) * centres))
  expected = np.sign(y) * np.expm1(abs(y))
  got_x = float(numerics.two_hot_decode(logits, -10.0, 10.0))
  assert got_x == pytest.approx(expected, rel=1e-4, abs=1e-4)
  if abs(x) < 2e4:
    assert got_x == pytest.approx(x, rel=1e-3, abs=1e-4)


def test_two_hot_decode_is_symexp_of_the_softmax_mean():
  logits = jax.random.normal(jax.random.PRNGKey(0), (4, 101))
  p = np.asarray(jax.nn.softmax(logits, -1), np.float64)
  y = p @ np.linspace(-10.0, 10.0, 101)
  np.testing.assert_allclose(np.asarray(numerics.two_hot_decode(logits, -10.0, 10.0)),
                             np.sign(y) * np.expm1(np.abs(y)), rtol=1e-4)


def test_q_target_is_the_min_of_a_random_pair_not_of_all_members():
  q_next = jnp.asarray([[1.0], [3.0], [2.0], [5.0], [4.0]])
  reward, gamma = jnp.asarray([0.5]), 0.9
  for pair, expected in (((3, 1), 0.5 + 0.9 * 3.0), ((4, 3), 0.5 + 0.9 * 4.0),
                         ((0, 2), 0.5 + 0.9 * 1.0)):
    got = critics_lib.tdmpc2_q_target(reward, q_next, gamma, jnp.asarray(pair))
    assert float(got[0]) == pytest.approx(expected)
  pairs = {tuple(sorted(np.asarray(critics_lib.random_pair(jax.random.PRNGKey(k), 5)).tolist()))
           for k in range(200)}
  assert pairs == set(itertools.combinations(range(5), 2))  # Distinct members, every pair.


def _perturbed(params, key, scale=0.3):
  leaves, tree = jax.tree_util.tree_flatten(params)
  keys = jax.random.split(key, len(leaves))
  return jax.tree_util.tree_unflatten(
      tree, [x + scale * jax.random.normal(k, x.shape) for x, k in zip(leaves, keys)])


def test_the_critic_loss_regresses_q_onto_tdmpc2s_target():
  """The preset's Q loss is the cross-entropy of its two-hot Q heads against two_hot(r / scale
  + gamma min(Q_i, Q_j)(z', a')), (i, j) a random pair of the EMA members, z' the online
  encoder's next latent, a' ~ pi(z'), computed here from those equations."""
  c = _tdmpc2_config()
  m, losses = ModelSettings.from_config(c), LossSettings.from_config(c)
  nets = build_networks(m)
  params = init_params(c, jax.random.PRNGKey(0))
  target = _perturbed(params, jax.random.PRNGKey(9))
  b, h, d = 6, c.horizon, m.latent_dim
  z = numerics.simnorm(jax.random.normal(jax.random.PRNGKey(1), (b, h + 2, d)))
  z_ema = numerics.simnorm(jax.random.normal(jax.random.PRNGKey(2), (b, h + 2, d)))
  action = jax.random.uniform(jax.random.PRNGKey(3), (b, h + 1, 4), minval=-1, maxval=1)
  reward = 10 * jax.random.uniform(jax.random.PRNGKey(4), (b, h + 1))
  key = jax.random.PRNGKey(5)
  policy = lambda p, zz: nets.actor.apply({'params': p['actor']}, zz)
  sample = lambda p, zz, k: nets.actor.apply({'params': p['actor']}, zz, k,
                                             method=nets.actor.sample)[0]
  loss = critics_lib.make_critic_loss(m, losses, nets.critics, policy, sample)
  terms, _, _ = loss(params, target, z, z_ema, None, action, reward, key)
  k_pair, _, k_next, _ = jax.random.split(key, 4)
  i, j = np.asarray(critics_lib.random_pair(k_pair, 5))
  a_next = sample(params, z[:, 1:], k_next)
  q_members = np.asarray(nets.critics.apply({'params': target['critics']}, z[:, 1:], a_next,
                                            method=nets.critics.q_value))
  assert q_members.shape == (5, b, h + 1)
  expected = np.asarray(reward) / m.value_scale + m.gamma * np.minimum(q_members[i], q_members[j])
  logits = np.asarray(nets.critics.apply({'params': params['critics']}, z[:, :h + 1], action,
                                         method=nets.critics.q_logits))
  log_p = logits - np.log(np.exp(logits).sum(-1, keepdims=True))
  probs = np.stack([[_np_two_hot(t, m.num_bins, m.vmin, m.vmax) for t in row]
                    for row in expected.reshape(-1, h + 1)]).reshape(expected.shape + (-1,))
  ce = -(probs[None] * log_p).sum(-1).mean()
  assert float(terms['q']) == pytest.approx(ce, rel=1e-4)
  # The min over all five members is another target, and another loss.
  all_min = np.asarray(reward) / m.value_scale + m.gamma * q_members.min(0)
  assert not np.allclose(all_min, expected)


def test_the_preset_has_cpus_budget_and_no_proposal():
  t, cpu = door_open_online.get_config('tdmpc2_cpu'), door_open_online.get_config('cpu')
  for name in ('model.width', 'model.latent_dim', 'train.batch_size', 'train.learning_rate',
               'online.update_ratio', 'online.env_steps', 'online.num_envs',
               'online.episode_steps', 'online.seed_steps', 'gamma'):
    section, field = name.split('.') if '.' in name else (None, name)
    get = (lambda cfg: cfg[section][field]) if section else (lambda cfg: cfg[field])
    assert get(t) == get(cpu), name
  assert t.plan.num_candidates == t.plan.num_prior_candidates == 8
  assert not t.online.act_proposal and 'proposal' not in t.eval.baselines
  assert (t.model.dynamics_type, t.model.latent_norm, t.critic.heads, t.critic.td_target,
          t.critic.actor, t.critic.num_q) == ('mlp', 'simnorm', 'two_hot', 'tdmpc2', 'maxq', 5)
  # The acting planner's rollouts per decision equal :cpu's: first round plus refinements.
  rollouts = lambda cfg, g, it: (cfg.plan.num_candidates + g + it * cfg.plan.num_refine)
  assert rollouts(t, t.online.act_num_gaussian, t.online.act_iterations) == rollouts(
      cpu, cpu.online.act_num_gaussian, cpu.online.act_iterations)
  check_config(t)


def _shrink(c) -> None:
  """The preset at smoke size, as `door_open_online.py:smoke` shrinks the online settings."""
  door_open.resize(c, width=16, heads=2, blocks=1)
  c.model.actor_hidden = c.critic.hidden = (16,)
  c.model.num_bins = 11
  c.critic.rollout_unroll = False
  c.train.batch_size, c.train.warmup_steps = 8, 2
  p = c.plan
  p.num_candidates = p.num_prior_candidates = 2
  p.num_gaussian = c.online.act_num_gaussian = 4
  p.iterations = c.online.act_iterations = 1
  p.num_refine, p.num_elites = 4, 2
  o = c.online
  o.env_steps, o.num_envs, o.episode_steps, o.seed_steps = 120, 2, 20, 40
  o.update_ratio, o.updates_per_call = 0.1, 1
  o.checkpoint_every, o.eval_every = 40, 80
  e = c.eval
  e.episodes = e.periodic_episodes = 1
  e.max_episode_steps, e.batch_size, e.noise_stds = 20, 2, (0.0,)


def test_a_tiny_tdmpc2_control_run_trains_and_evaluates(tmp_path):
  from ld_mpc_jax.runs import train  # pylint: disable=g-import-not-at-top (environments)
  c = _tdmpc2_config()
  train.train_and_evaluate(c, str(tmp_path))
  with open(tmp_path / 'online.csv') as f:
    rows = list(csv.DictReader(f))
  planned = [r for r in rows if r['acting'] == 'planner']
  assert rows[0]['acting'] == 'random' and planned
  for r in planned:  # No proposal candidate ever wins: there are none.
    assert math.isnan(float(r['won_proposal'])) or float(r['won_proposal']) == 0.0
  with open(tmp_path / 'losses.csv') as f:
    header = next(csv.reader(f))
  assert 'loss_consistency' in header and 'loss_q' in header
  assert 'loss_act' not in header and 'loss_dyn' not in header  # Weight 0: left out.
  assert (tmp_path / 'eval.csv').exists() and (tmp_path / 'report.md').exists()
