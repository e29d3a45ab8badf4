"""The loss terms (ld_mpc_jax.learn.losses, and the kinds' own) against hand-computed values."""

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.learn import losses
from ld_mpc_jax.model.settings import LossSettings, ModelSettings


def test_maxq_actor_climbs_a_toy_q(smoke_config):
  """The max-Q policy's gradient: with Q(z, a) = w . a (linear heads, z ignored), descending the
  actor loss moves the policy's mode toward sign(w) on every action dimension."""
  import optax
  from ld_mpc_jax.model import models
  from ld_mpc_jax.model.actors import maxq_actor_loss
  c = smoke_config
  c.critic.actor, c.critic.hidden = 'maxq', ()
  nets = models.build_networks(ModelSettings.from_config(c))
  params = models.init_params(c, jax.random.key(0))
  d = c.model.latent_dim
  w = np.array([1.0, -1.0, 1.0, -1.0], np.float32)
  kernel = np.zeros(params['critics']['q']['heads']['dense_0']['kernel'].shape, np.float32)
  kernel[:, d:, 0] = w  # Q_j(z, a) = w . a for both heads.
  params['critics']['q']['heads']['dense_0']['kernel'] = jnp.asarray(kernel)
  params['critics']['q']['heads']['dense_0']['bias'] *= 0.0
  z = jax.random.normal(jax.random.key(1), (16, d))
  mode = jax.jit(lambda p: nets.actor.apply({'params': p['actor']}, z))
  before = float(jnp.mean(mode(params) @ w))
  opt = optax.adam(1e-2)
  state = opt.init(params)

  @jax.jit  # One program per step: the optimiser's update op by op compiles many small ones.
  def step(params, state, key):
    g = jax.grad(lambda p: maxq_actor_loss(nets, p, z, key, 1e-4))(params)
    updates, state = opt.update(g, state, params)
    q_grad = jnp.abs(g['critics']['q']['heads']['dense_0']['kernel']).max()
    return optax.apply_updates(params, updates), state, q_grad

  for i in range(100):
    params, state, q_grad = step(params, state, jax.random.key(i))
    assert float(q_grad) == 0.0
  after = mode(params)
  assert float(jnp.mean(after @ w)) > before + 1.0
  assert bool(jnp.all(jnp.sign(jnp.mean(after, 0)) == w))


# --- Each term against hand-computed values on tiny arrays. -------------------------------
# Fakes stand in for the networks where a term calls one: a module whose `apply` predicts
# zeros makes a denoising loss with x0-prediction the mean square of the clean data.

class _Zeros:
  """A module whose apply returns zeros shaped as its first array input (or a fixed output)."""

  def __init__(self, out=None):
    self.out = out

  def apply(self, variables, x, *args, **kwargs):
    return jnp.zeros_like(x) if self.out is None else self.out


def _cfg():
  import ml_collections
  return ml_collections.ConfigDict(dict(
      horizon=2, action_dim=2, gamma=0.5, diffusion=dict(prediction='x0'),
      model=dict(num_bins=5, vmin=-2.0, vmax=2.0), critic=dict(entropy_coef=0.1),
      loss=dict(w_dyn=1.0, w_act=2.0, w_rew=3.0, w_val=4.0, w_actor=5.0, w_consistency=6.0,
                w_q=7.0, w_v=8.0, w_demo_bc=9.0, w_noise_inv=10.0, w_progress=11.0,
                w_novelty=12.0)))


def _losses():
  """The loss settings' fields that the losses read, at _cfg()'s values."""
  return types.SimpleNamespace(**_cfg().loss, entropy_coef=0.1)


def _model():
  """The model settings' fields that the kinds' losses read, at _cfg()'s values."""
  return types.SimpleNamespace(horizon=2, action_dim=2, gamma=0.5, prediction='x0', num_bins=5,
                               vmin=-2.0, vmax=2.0)


Z = jnp.arange(2 * 4 * 3, dtype=jnp.float32).reshape(2, 4, 3) / 10.0  # [B=2, H+2=4, D=3]
A = jnp.arange(2 * 3 * 2, dtype=jnp.float32).reshape(2, 3, 2) / 10.0 - 0.5  # [B, H+1=3, A=2]
PARAMS = {'proposal': {}, 'dynamics': {}, 'actor': {}, 'critics': {}}


def test_reward_loss_hand_computed():
  # 5 bins on [-2, 2]; reward 0 is all on the middle bin: CE = -log p_2.
  probs = jnp.array([0.1, 0.1, 0.6, 0.1, 0.1])
  got = losses.reward_loss(jnp.log(probs)[None, None], jnp.zeros((1, 1)), 5, -2.0, 2.0)
  np.testing.assert_allclose(got, -np.log(0.6), rtol=1e-5)


def test_behaviour_value_loss_hand_computed():
  """Targets: window returns of the rewards bootstrapped with the EMA head's V(z_{H+1})."""
  from ld_mpc_jax.model.objective import Behaviour
  # The EMA objective's value logits all on the middle bin: V_ema = symexp(0) = 0.
  v_tgt = jnp.log(jnp.array([1e-9, 1e-9, 1.0, 1e-9, 1e-9]))
  nets = type('Nets', (), {'objective': _Zeros((None, jnp.broadcast_to(v_tgt, (1, 3, 5))))})
  reward = jnp.array([[0.0, 0.0, np.expm1(0.25)]])  # Targets: 0.25 e, 0.5 e, e (e = expm1 .25).
  e = np.expm1(0.25)
  v_logits = jnp.zeros((1, 3, 5))  # Uniform: CE = log 5 whatever the target.
  loss, target_mean = Behaviour.loss(_model(), nets, {'objective': {}},
                                     jnp.zeros((1, 4, 3)), jnp.zeros((1, 3, 2)), reward, v_logits)
  np.testing.assert_allclose(loss, np.log(5.0), rtol=1e-5)
  np.testing.assert_allclose(target_mean, (0.25 * e + 0.5 * e + e) / 3, rtol=1e-5)


def test_consistency_loss_hand_computed():
  got = losses.consistency_loss(jnp.array([[[1.0, 2.0]]]), jnp.array([[[0.0, 0.0]]]))
  np.testing.assert_allclose(got, 2.5, rtol=1e-6)


def test_weighted_sum_order_and_absent_terms():
  terms = {name: jnp.asarray(1.0) for name, _ in losses.WEIGHTS}
  np.testing.assert_allclose(losses.weighted_sum(terms, _losses()), 78.0)
  del terms['q'], terms['consistency']  # Absent terms count 0.
  np.testing.assert_allclose(losses.weighted_sum(terms, _losses()), 78.0 - 7.0 - 6.0)


@pytest.mark.parametrize('kind', ['diffusion_seq', 'diffusion_step'])
def test_diffusion_proposal_losses_hand_computed(kind):
  """x0-prediction of zeros: the loss is the mean square of the denoised actions."""
  from ld_mpc_jax.model.proposals import PROPOSALS
  got = PROPOSALS.get(kind).loss(_model(), _Zeros(), PARAMS, Z, A, jax.random.key(0), {})
  want = jnp.mean(A[:, :2] ** 2) if kind == 'diffusion_seq' else jnp.mean(A ** 2)
  np.testing.assert_allclose(got, want, rtol=1e-6)


def test_gaussian_proposal_nll_hand_computed():
  from ld_mpc_jax.model.proposals import PROPOSALS, gaussian_nll
  np.testing.assert_allclose(gaussian_nll(jnp.zeros(2), jnp.log(jnp.array([1.0, 2.0])),
                                          jnp.array([1.0, 2.0])),
                             np.mean([0.5, 0.5 + np.log(2.0)]), rtol=1e-6)
  module = _Zeros((jnp.zeros((6, 2)), jnp.zeros((6, 2))))  # mean 0, log std 0
  got = PROPOSALS.get('mlp').loss(_model(), module, PARAMS, Z, A, jax.random.key(0), {})
  np.testing.assert_allclose(got, 0.5 * jnp.mean(A ** 2), rtol=1e-6)


@pytest.mark.parametrize('kind', ['diffusion_ar', 'diffusion_traj', 'mlp'])
def test_dynamics_losses_hand_computed(kind):
  """Predicting zeros: the mean square of the next latents (all H+1 of them for one-step kinds,
  z_{1:H} for the trajectory kind)."""
  from ld_mpc_jax.model.dynamics import DYNAMICS
  got = DYNAMICS.get(kind).loss(_model(), _Zeros(), PARAMS, Z, A, jax.random.key(0), {})
  want = jnp.mean(Z[:, 1:3] ** 2) if kind == 'diffusion_traj' else jnp.mean(Z[:, 1:] ** 2)
  np.testing.assert_allclose(got, want, rtol=1e-6)


@pytest.mark.parametrize('kind', ['bc', 'awr'])
def test_regression_actor_losses_hand_computed(kind):
  from ld_mpc_jax.model.actors import ACTORS
  nets = type('Nets', (), {'actor': _Zeros(jnp.zeros((2, 3, 2)))})
  weights = jnp.array([[1.0, 0.0, 2.0], [0.0, 0.0, 1.0]])
  got = ACTORS.get(kind).loss(_losses(), nets, PARAMS, Z, A, weights, jax.random.key(0))
  sq = jnp.sum(A ** 2, axis=-1)  # [B, H+1]
  want = jnp.mean(sq) if kind == 'bc' else jnp.mean(weights * sq)  # BC ignores the weights.
  np.testing.assert_allclose(got, want, rtol=1e-6)


def test_maxq_actor_loss_hand_computed():
  """E[alpha log pi - mean_j Q_j] with a fake actor (log pi = -1) and Q ensemble (1 and 3)."""
  from ld_mpc_jax.model.actors import ACTORS

  class Actor(_Zeros):
    def sample(self):
      pass

    def apply(self, variables, z, key=None, method=None):
      return jnp.zeros(z.shape[:-1] + (2,)), -jnp.ones(z.shape[:-1])

  class Critics(_Zeros):
    def q_value(self):
      pass

    def apply(self, variables, z, a, method=None):
      return jnp.stack([jnp.ones(z.shape[:-1]), 3 * jnp.ones(z.shape[:-1])])

  nets = type('Nets', (), {'actor': Actor(), 'critics': Critics()})
  got = ACTORS.get('maxq').loss(_losses(), nets, PARAMS, Z, A, None, jax.random.key(0))
  np.testing.assert_allclose(got, 0.1 * -1.0 - 2.0, rtol=1e-6)


def test_loss_metrics_and_total(smoke_config):
  """The logged names stay those of the single closure this replaced, and `loss` is the
  weighted sum of the logged terms."""
  from ld_mpc_jax.configs.overrides import with_overrides
  from ld_mpc_jax.model import models
  expected = {
      'smoke': {'loss', 'loss_dyn', 'loss_act', 'loss_rew', 'loss_val', 'loss_actor',
                'loss_consistency', 'loss_q', 'loss_v', 'q_mean', 'v_mean', 'advantage_std',
                'awr_weight_mean'},
      'behaviour': {'loss', 'loss_dyn', 'loss_act', 'loss_rew', 'loss_val', 'loss_actor',
                    'value_target_mean'},
  }
  overrides = {'smoke': {}, 'behaviour': {'critic.value': 'behaviour',
                                          'critic.actor': 'bc',
                                          'critic.latent_rollout': False}}
  rng = np.random.default_rng(0)
  h = smoke_config.horizon
  batch = {'obs': jnp.asarray(rng.normal(size=(2, h + 2, 39)), jnp.float32),
           'action': jnp.asarray(rng.uniform(-1, 1, (2, h + 1, 4)), jnp.float32),
           'reward': jnp.asarray(rng.uniform(0, 1, (2, h + 1)), jnp.float32)}
  for name, names in expected.items():
    c = with_overrides(smoke_config, overrides[name])
    params = models.init_params(c, jax.random.key(0))
    # One jitted program: operation by operation, the loss compiles hundreds of small ones.
    m = ModelSettings.from_config(c)
    loss_fn = jax.jit(losses.make_loss_fn(m, LossSettings.from_config(c),
                                          models.build_networks(m)))
    loss, metrics = loss_fn(params, params, batch, jax.random.key(1))
    assert set(metrics) == names, name
    terms = {n: metrics[f'loss_{n}'] for n, _ in losses.WEIGHTS if f'loss_{n}' in metrics}
    np.testing.assert_allclose(loss, losses.weighted_sum(terms, LossSettings.from_config(c)),
                               rtol=1e-6)


def test_rolled_and_unrolled_training_rollouts_agree(smoke_config):
  """`critic.rollout_unroll` changes the compiled program, not the latents: the smoke preset's
  rolled scan (faster to compile, for the tests) stands for the unrolled one of real runs."""
  from ld_mpc_jax.model import models
  c = smoke_config
  params = models.init_params(c, jax.random.key(0))
  z0 = jax.random.normal(jax.random.key(1), (3, c.model.latent_dim))
  actions = jax.random.uniform(jax.random.key(2), (3, c.horizon, c.action_dim), minval=-1.0,
                               maxval=1.0)
  out = {}
  for unroll in (False, True):
    c.critic.rollout_unroll = unroll
    m = ModelSettings.from_config(c)
    rollout = losses.make_model_rollout(m, LossSettings.from_config(c), models.build_networks(m))
    out[unroll] = np.asarray(jax.jit(rollout)(params, z0, actions, jax.random.key(3)))
  assert out[True].shape == (3, c.horizon + 1, c.model.latent_dim)
  assert np.abs(out[True][:, -1] - out[True][:, 0]).max() > 1e-3  # The latents move.
  np.testing.assert_allclose(out[False], out[True], rtol=1e-5, atol=1e-6)


def test_reward_balance_weighs_the_rare_class_as_much_as_the_common_one():
  """loss.reward_balance = 1: one positive reward among ten weighs as much in total as the nine
  zeros; 0 is the plain mean; a batch without positives is the plain mean whatever the balance."""
  from ld_mpc_jax.ops.numerics import soft_cross_entropy, two_hot
  reward = jnp.zeros((2, 5)).at[0, 3].set(1.0)  # One solved step of ten.
  logits = jax.random.normal(jax.random.key(0), (2, 5, 5))
  ce = soft_cross_entropy(logits, two_hot(reward, 5, -2.0, 2.0))
  plain = losses.reward_loss(logits, reward, 5, -2.0, 2.0)
  np.testing.assert_allclose(plain, ce.mean(), rtol=1e-6)
  balanced = losses.reward_loss(logits, reward, 5, -2.0, 2.0, balance=1.0)
  zeros = (ce.sum() - ce[0, 3]) / 9
  np.testing.assert_allclose(balanced, 0.5 * ce[0, 3] + 0.5 * zeros, rtol=1e-5)
  half = losses.reward_loss(logits, reward, 5, -2.0, 2.0, balance=0.5)  # Weight 3 against 1.
  np.testing.assert_allclose(half, (3 * ce[0, 3] + 9 * zeros) / 12, rtol=1e-5)
  none = jnp.zeros((2, 5))
  np.testing.assert_allclose(losses.reward_loss(logits, none, 5, -2.0, 2.0, balance=1.0),
                             losses.reward_loss(logits, none, 5, -2.0, 2.0), rtol=1e-6)


W = jnp.array([[3.0, 1.0, 0.5], [0.2, 1.0, 2.0]])  # Weights of the window's pairs [B, H+1].


@pytest.mark.parametrize('kind', ['diffusion_seq', 'diffusion_step', 'mlp'])
def test_weighted_proposal_losses_hand_computed(kind):
  """loss.act_weighting='advantage': a sequence kind weighs each window by its first pair's
  weight, a single-step kind each pair by its own; weights of 1 give the unweighted loss."""
  from ld_mpc_jax.model.proposals import PROPOSALS
  module = _Zeros((jnp.zeros((6, 2)), jnp.zeros((6, 2)))) if kind == 'mlp' else _Zeros()
  loss = lambda w: PROPOSALS.get(kind).loss(_model(), module, PARAMS, Z, A, jax.random.key(0),
                                            {}, weights=w)
  scale = 0.5 if kind == 'mlp' else 1.0  # The NLL at mean 0, std 1 is half the square.
  if kind == 'diffusion_seq':
    want = jnp.mean(W[:, 0] * jnp.mean(A[:, :2] ** 2, axis=(1, 2)))
  else:
    want = scale * jnp.mean(W * jnp.mean(A ** 2, axis=-1))
  np.testing.assert_allclose(loss(W), want, rtol=1e-6)
  np.testing.assert_allclose(loss(jnp.ones_like(W)), loss(None), rtol=1e-6)
  assert abs(float(loss(W)) - float(loss(None))) > 1e-3  # The weights change it.


def _loss_metrics(config, batch):
  from ld_mpc_jax.model import models
  params = models.init_params(config, jax.random.key(0))
  m = ModelSettings.from_config(config)
  loss_fn = jax.jit(losses.make_loss_fn(m, LossSettings.from_config(config),
                                        models.build_networks(m)))
  return loss_fn(params, params, batch, jax.random.key(1))[1]


def test_advantage_weighted_proposal_loss_through_the_critics(smoke_config):
  """At awr_temperature 0 every critic weight is exp(0) = 1: the advantage-weighted proposal
  loss is the uniform one; at 3 it differs, and no other term moves."""
  from ld_mpc_jax.configs.overrides import with_overrides
  rng = np.random.default_rng(0)
  h = smoke_config.horizon
  batch = {'obs': jnp.asarray(rng.normal(size=(4, h + 2, 39)), jnp.float32),
           'action': jnp.asarray(rng.uniform(-1, 1, (4, h + 1, 4)), jnp.float32),
           'reward': jnp.asarray(rng.uniform(0, 1, (4, h + 1)), jnp.float32)}
  uniform = _loss_metrics(with_overrides(smoke_config, {'critic.awr_temperature': 3.0}), batch)
  flat = _loss_metrics(with_overrides(smoke_config, {'loss.act_weighting': 'advantage',
                                                     'critic.awr_temperature': 0.0}), batch)
  weighted = _loss_metrics(with_overrides(smoke_config, {'loss.act_weighting': 'advantage',
                                                         'critic.awr_temperature': 3.0}), batch)
  np.testing.assert_allclose(flat['loss_act'], uniform['loss_act'], rtol=1e-5)
  assert abs(float(weighted['loss_act']) - float(uniform['loss_act'])) > 1e-4
  for name in ('loss_dyn', 'loss_rew', 'loss_q', 'loss_v', 'loss_actor'):
    np.testing.assert_allclose(weighted[name], uniform[name], rtol=1e-6, err_msg=name)


def test_act_weighting_refuses_unknown_kinds_and_a_model_without_critics(smoke_config):
  from ld_mpc_jax.configs.overrides import with_overrides
  from ld_mpc_jax.model import models
  with pytest.raises(ValueError, match='act_weighting must be one of'):
    LossSettings.from_config(with_overrides(smoke_config, {'loss.act_weighting': 'best'})
                             ).check_weights()
  c = with_overrides(smoke_config, {'loss.act_weighting': 'advantage', 'critic.value': 'behaviour',
                                    'critic.actor': 'bc', 'critic.latent_rollout': False})
  m = ModelSettings.from_config(c)
  with pytest.raises(ValueError, match='has none'):
    losses.make_loss_fn(m, LossSettings.from_config(c), models.build_networks(m))


def test_proposal_targets_take_the_planned_sequences_where_a_window_has_one():
  """loss.act_target='planned': a window's first H actions become its planned sequence where
  has_plan is 1, its executed ones elsewhere; the last action stays; no plans: the actions."""
  rng = np.random.default_rng(0)
  h, b = 3, 4
  action = jnp.asarray(rng.uniform(-1, 1, (b, h + 1, 2)), jnp.float32)
  plan = jnp.asarray(rng.uniform(-1, 1, (b, h, 2)), jnp.float32)
  has_plan = jnp.asarray([1.0, 0.0, 1.0, 0.0])
  out = np.asarray(losses.proposal_targets({'plan': plan, 'has_plan': has_plan}, action, h))
  expected = np.array(action)
  expected[[0, 2], :h] = np.asarray(plan)[[0, 2]]
  np.testing.assert_array_equal(out, expected)
  assert losses.proposal_targets({}, action, h) is action


def test_planned_targets_move_only_the_proposal_loss(smoke_config):
  """Through the loss: with plans on every window the proposal's loss differs from the executed
  actions' and no other term moves; with has_plan 0 everywhere it is the executed actions' loss."""
  from ld_mpc_jax.configs.overrides import with_overrides
  rng = np.random.default_rng(0)
  h = smoke_config.horizon
  batch = {'obs': jnp.asarray(rng.normal(size=(4, h + 2, 39)), jnp.float32),
           'action': jnp.asarray(rng.uniform(-1, 1, (4, h + 1, 4)), jnp.float32),
           'reward': jnp.asarray(rng.uniform(0, 1, (4, h + 1)), jnp.float32),
           'plan': jnp.asarray(rng.uniform(-1, 1, (4, h, 4)), jnp.float32)}
  executed = _loss_metrics(smoke_config, batch)
  planned_config = with_overrides(smoke_config, {'loss.act_target': 'planned'})
  planned = _loss_metrics(planned_config, dict(batch, has_plan=jnp.ones(4)))
  none = _loss_metrics(planned_config, dict(batch, has_plan=jnp.zeros(4)))
  assert float(planned['loss_act']) != pytest.approx(float(executed['loss_act']), rel=1e-3)
  np.testing.assert_allclose(float(none['loss_act']), float(executed['loss_act']), rtol=1e-6)
  for k in executed:
    if k not in ('loss', 'loss_act'):
      np.testing.assert_allclose(float(planned[k]), float(executed[k]), rtol=1e-5, err_msg=k)


def test_planned_targets_need_a_sequence_proposal(smoke_config):
  from ld_mpc_jax.configs.overrides import with_overrides
  from ld_mpc_jax.model import config_checks
  with pytest.raises(ValueError, match='act_target must be one of'):
    config_checks.check_config(with_overrides(smoke_config, {'loss.act_target': 'best'}))
  with pytest.raises(ValueError, match=r"^config.loss.act_target='planned' trains a sequence"):
    config_checks.check_config(with_overrides(smoke_config, {'loss.act_target': 'planned',
                                                             'model.proposal_type': 'mlp'}))
