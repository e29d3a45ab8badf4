"""The learned progress reward (ld_mpc_jax.model.progress): its targets, its fit on a toy task,
its term in the loss and its bonus in J."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.data import dataset as dataset_lib
from ld_mpc_jax.data import replay
from ld_mpc_jax.model import progress
from ld_mpc_jax.model.settings import LossSettings, ModelSettings

ON = {'loss.w_progress': 1.0, 'plan.progress_weight': 5.0}


def _episode(length, solved_after=None, obs_dim=3):
  success = np.zeros(length, bool)
  if solved_after is not None:
    success[solved_after:] = True
  return dict(obs=np.zeros((length + 1, obs_dim), np.float32),
              action=np.zeros((length, 4), np.float32),
              reward=success.astype(np.float32), success=success)


def test_targets_ramp_to_the_first_success_and_are_zero_on_failures():
  ds = dataset_lib.Dataset.from_episodes([_episode(5, solved_after=2), _episode(3)])
  targets = replay.progress_targets(ds)
  # The success follows action 2, so observation 3 is the first solved state.
  np.testing.assert_allclose(targets[:6], [0, 1 / 3, 2 / 3, 1, 1, 1], rtol=1e-6)
  np.testing.assert_array_equal(targets[6:], np.zeros(4))
  buffer = replay.ReplayBuffer(ds, seq_len=3, seed=0, progress=True)
  batch = buffer.sample(8)
  assert batch['progress'].shape == (8, 3)
  plain = replay.ReplayBuffer(ds, seq_len=3, seed=0).sample(8)  # The same draws.
  np.testing.assert_array_equal(plain['obs'], batch['obs'])
  assert 'progress' not in plain


def test_the_head_learns_to_rank_a_demonstrations_later_states_above_its_earlier_ones():
  """Toy task: latents walk from a start point to a goal along a line (demonstrations, and one
  agent episode that reaches the goal), or wander near the start (failed episodes). Fitted on
  these, Phi ranks a held-out demonstration's states in their order."""
  import optax  # pylint: disable=g-import-not-at-top
  rng = np.random.default_rng(0)
  d, length = 8, 20
  direction = rng.normal(size=d)
  direction /= np.linalg.norm(direction)

  def walk(reach):
    t = np.linspace(0, reach, length + 1)[:, None]
    return t * direction + 0.05 * rng.normal(size=(length + 1, d))

  episodes = [(walk(1.0), True) for _ in range(6)] + [(walk(0.2), False) for _ in range(6)]
  z = np.stack([e for e, _ in episodes]).astype(np.float32)
  target = np.stack([np.minimum(np.arange(length + 1) / length, 1.0) if ok
                     else np.zeros(length + 1) for _, ok in episodes]).astype(np.float32)
  net = progress.Progress((32, 32))
  params = {'progress': net.init(jax.random.key(0), z[0, 0])['params']}
  opt = optax.adam(3e-3)
  state = opt.init(params)

  @jax.jit
  def step(params, state):
    g = jax.grad(lambda p: progress.loss(net, p, z, target))(params)
    updates, state = opt.update(g, state, params)
    return optax.apply_updates(params, updates), state

  before = float(progress.loss(net, params, z, target))
  for _ in range(300):
    params, state = step(params, state)
  assert float(progress.loss(net, params, z, target)) < before - 0.1
  held_out = walk(1.0).astype(np.float32)
  phi = np.asarray(progress.phi(net, params, held_out))
  ranks = np.argsort(np.argsort(phi))
  rho = np.corrcoef(ranks, np.arange(length + 1))[0, 1]  # Spearman's rank correlation.
  assert rho > 0.9, rho
  assert phi[-1] > 0.7 and phi[0] < 0.3


def test_the_loss_has_the_term_only_with_the_head_and_targets(smoke_config):
  from ld_mpc_jax.learn import losses  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.model import models  # pylint: disable=g-import-not-at-top
  c = with_overrides(smoke_config, ON)
  params = models.init_params(c, jax.random.key(0))
  assert 'progress' in params and 'progress' not in jax.eval_shape(  # Traced, not compiled.
      lambda: models.init_params(smoke_config, jax.random.key(0)))
  rng = np.random.default_rng(0)
  h = c.horizon
  batch = {'obs': jnp.asarray(rng.normal(size=(2, h + 2, 39)), jnp.float32),
           'action': jnp.asarray(rng.uniform(-1, 1, (2, h + 1, 4)), jnp.float32),
           'reward': jnp.zeros((2, h + 1), jnp.float32),
           'progress': jnp.asarray(rng.uniform(0, 1, (2, h + 2)), jnp.float32)}
  m = ModelSettings.from_config(c)
  loss_fn = losses.make_loss_fn(m, LossSettings.from_config(c), models.build_networks(m))
  # The metrics and the gradient from one compiled program (compiling dominates this test).
  (_, metrics), grads = jax.jit(jax.value_and_grad(loss_fn, has_aux=True))(
      params, params, batch, jax.random.key(1))
  nets = models.build_networks(ModelSettings.from_config(c))
  z = models.encode(params, batch['obs'])
  expected = progress.loss(nets.progress, params, z, batch['progress'])
  np.testing.assert_allclose(metrics['loss_progress'], expected, rtol=1e-5)
  assert float(jnp.abs(grads['progress']['mlp']['dense_0']['kernel']).max()) > 0
  del batch['progress']
  _, metrics = jax.eval_shape(loss_fn, params, params, batch, jax.random.key(1))
  assert 'loss_progress' not in metrics and 'loss_rew' in metrics


def test_j_gains_w_gamma_h_phi_of_the_last_latent(smoke_config):
  from ld_mpc_jax.model import models, objective  # pylint: disable=g-import-not-at-top
  c = with_overrides(smoke_config, ON)
  m = ModelSettings.from_config(c)
  nets = models.build_networks(m)
  params = models.init_params(c, jax.random.key(0))
  k, h, d = 5, c.horizon, c.model.latent_dim
  latents = jax.random.normal(jax.random.key(1), (k, h + 1, d))
  actions = jax.random.uniform(jax.random.key(2), (k, h, 4), minval=-1, maxval=1)
  shaped = objective.make_member_scores(m, nets, c.plan.progress_weight)(params, latents, actions)
  plain = objective.make_member_scores(m, nets, 0.0)(params, latents, actions)
  phi = progress.phi(nets.progress, params, latents[:, -1])
  np.testing.assert_allclose(shaped - plain, np.broadcast_to(5.0 * c.gamma ** h * phi, plain.shape),
                             rtol=1e-5, atol=1e-6)


def test_the_weight_in_j_needs_the_head(smoke_config):
  from ld_mpc_jax.runs.checks import validate_config  # pylint: disable=g-import-not-at-top
  with pytest.raises(ValueError, match='needs the progress head'):
    validate_config(with_overrides(smoke_config, {'plan.progress_weight': 1.0}))
  with pytest.raises(ValueError, match='must be >= 0'):
    validate_config(with_overrides(smoke_config, {'loss.w_progress': -1.0}))
