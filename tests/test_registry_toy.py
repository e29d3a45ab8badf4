"""A new dynamics kind is one registry entry: a toy linear latent map, registered here alone,
trains and plans with no library file changed."""

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.model import models
from ld_mpc_jax.plan import planner
from ld_mpc_jax.learn import train_state
from ld_mpc_jax.model.dynamics import DYNAMICS

CALLS = []  # One entry per trace of the toy module's __call__.


class LinearLatentMap(nn.Module):
  """z_{i+1} = W [z_i, a_i] + b."""
  latent_dim: int

  @nn.compact
  def __call__(self, z, a):
    CALLS.append(z.shape)
    return nn.Dense(self.latent_dim, name='linear')(jnp.concatenate([z, a], axis=-1))


class ToyLinear:
  """The entry: everything the kind needs, in one place."""
  one_step = True
  conditioning = (('linear',),)

  def build(self, model):  # model: the ModelSettings (ld_mpc_jax.model.settings).
    return LinearLatentMap(model.latent_dim)

  def init_args(self, model):
    return jnp.zeros((1, model.latent_dim)), jnp.zeros((1, model.action_dim))

  def loss(self, model, module, params, z, action, key, rngs):
    n = action.shape[0] * action.shape[1]
    z_in, a_in = z[:, :-1].reshape(n, -1), action.reshape(n, -1)
    pred = module.apply({'params': params['dynamics']}, z_in, a_in)
    return jnp.mean((pred - jax.lax.stop_gradient(z[:, 1:].reshape(n, -1))) ** 2)

  def make_step(self, model, module, steps, eta):
    return lambda params, z, a, key: module.apply({'params': params['dynamics']}, z, a)


@pytest.fixture
def toy_config(smoke_config):
  DYNAMICS.register('toy_linear', ToyLinear())
  CALLS.clear()
  yield with_overrides(smoke_config, {'model.dynamics_type': 'toy_linear',
                                      'plan.num_candidates': 4})
  DYNAMICS.unregister('toy_linear')


def _batch(config, b=8):
  rng = np.random.default_rng(0)
  h = config.horizon
  return {'obs': jnp.asarray(rng.normal(size=(b, h + 2, config.obs_dim)), jnp.float32),
          'action': jnp.asarray(rng.uniform(-1, 1, (b, h + 1, config.action_dim)), jnp.float32),
          'reward': jnp.asarray(rng.uniform(0, 1, (b, h + 1)), jnp.float32)}


def test_toy_dynamics_trains(toy_config):
  learn = train_state.LearnSettings.from_config(toy_config)
  state = train_state.create_train_state(learn, jax.random.key(0))
  assert set(state.params['dynamics']) == {'linear'}
  update, batch = train_state.make_update(learn), _batch(toy_config)
  losses = []
  for i in range(8):
    state, metrics = update(state, batch, jax.random.key(i))
    losses.append(float(metrics['loss_dyn']))
  assert CALLS, 'the toy module was never called'
  assert np.all(np.isfinite(losses)) and losses[-1] < losses[0]


def test_toy_dynamics_plans(toy_config):
  params = models.init_params(toy_config, jax.random.key(0))
  plan = planner.make_plan(toy_config)
  z = models.encode(params, np.zeros(toy_config.obs_dim))
  out = plan(params, z, jax.random.key(1))
  assert CALLS, 'the toy module was never called'
  assert out.action.shape == (toy_config.action_dim,)
  assert bool(jnp.all(jnp.isfinite(out.action))) and bool(jnp.all(jnp.abs(out.action) <= 1.0))
  assert out.scores.shape == (4,)
  # The rollout goes through the toy map: other weights, other scores for the same candidates.
  other = jax.tree_util.tree_map(lambda x: x + 0.5, params['dynamics'])
  moved = plan(dict(params, dynamics=other), z, jax.random.key(1))
  assert float(jnp.max(jnp.abs(moved.scores - out.scores))) > 1e-6


def test_unknown_dynamics_kind_is_a_one_line_error(smoke_config):
  config = with_overrides(smoke_config, {'model.dynamics_type': 'toy_linear'})
  with pytest.raises(ValueError, match=r"^config.model.dynamics_type must be one of "
                                       r"'diffusion_ar', 'diffusion_traj', 'mlp', 'conv_frames', "
                                       r"got 'toy_linear'$"):
    models.init_params(config, jax.random.key(0))


def test_task_conditioning_is_declared_by_the_kind(toy_config):
  """Multi-task: the toy's declared input layer gets a task bias; a declared layer the module
  lacks is an error, not a silently unconditioned network."""
  from ld_mpc_jax.configs import mt10
  mt = with_overrides(mt10.get_config('smoke'), {'model.dynamics_type': 'toy_linear'})
  params = models.init_params(mt, jax.random.key(0))
  assert set(params['task']['proj']['dynamics']) == {'linear'}

  class Undeclared(ToyLinear):
    conditioning = (('nosuch',),)
  DYNAMICS.register('toy_undeclared', Undeclared())
  try:
    with pytest.raises(ValueError, match="has no input layer 'nosuch'"):
      models.init_params(with_overrides(mt, {'model.dynamics_type': 'toy_undeclared'}),
                         jax.random.key(0))
  finally:
    DYNAMICS.unregister('toy_undeclared')
