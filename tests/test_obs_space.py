"""`model.encoder_type='identity'` (issue 105): the latent is the standardised observation, so
the dynamics model predicts the next observation and `plan` searches in observation space (the
D-MPC-style planner the latent one is compared with), with nothing else of the agent changed."""

import jax
import numpy as np
import pytest

from ld_mpc_jax import LearnSettings, create_train_state, init_params, make_update
from ld_mpc_jax.configs import door_open
from ld_mpc_jax.model import models
from ld_mpc_jax.runs.checks import validate_config
from ld_mpc_jax.plan.planner import make_plan
from ld_mpc_jax.model.settings import ModelSettings


def obs_space_config():
  c = door_open.get_config('smoke')
  c.model.encoder_type, c.model.latent_dim, c.model.normalize_dynamics = 'identity', 39, False
  c.model.dropout, c.train.learning_rate = 0.0, 3e-3
  return c


def test_the_latent_is_the_standardised_observation():
  config = obs_space_config()
  params = init_params(config, jax.random.key(0))
  assert sorted(params['encoder']) == ['obs_mean', 'obs_std']  # Nothing to learn.
  obs = np.random.default_rng(0).normal(2.0, 3.0, (50, 39)).astype(np.float32)
  params = models.set_obs_normalization(params, obs)
  z = models.encode(params, obs[:4])
  want = (obs[:4] - obs.mean(0)) / obs.std(0)
  np.testing.assert_allclose(np.asarray(z), want, rtol=1e-4, atol=1e-4)
  out = make_plan(config)(params, z[0], jax.random.key(1))
  assert out.action.shape == (config.action_dim,) and np.all(np.isfinite(out.scores))
  assert out.candidates.shape[1:] == (config.horizon, config.action_dim)


def test_an_update_trains_the_observation_dynamics():
  config = obs_space_config()
  learn = LearnSettings.from_config(config)
  state = create_train_state(learn, jax.random.key(0))
  rng = np.random.default_rng(0)
  h = config.horizon
  batch = {'obs': rng.normal(size=(8, h + 2, 39)).astype(np.float32),
           'action': rng.uniform(-1, 1, (8, h + 1, 4)).astype(np.float32),
           'reward': rng.uniform(0, 5, (8, h + 1)).astype(np.float32)}
  before = jax.tree_util.tree_map(np.array, state.params['dynamics'])
  encoder = jax.tree_util.tree_map(np.array, state.params['encoder'])
  update, losses = make_update(learn), []
  for _ in range(20):
    state, metrics = update(state, batch, jax.random.key(1))
    losses.append(float(metrics['loss']))
  assert np.all(np.isfinite(losses)) and losses[-1] < losses[0], losses
  moved = jax.tree_util.tree_map(lambda a, b: float(np.abs(np.asarray(a) - b).max()),
                                 state.params['dynamics'], before)
  assert max(jax.tree_util.tree_leaves(moved)) > 0
  jax.tree_util.tree_map(np.testing.assert_array_equal, state.params['encoder'], encoder)


@pytest.mark.parametrize('field,value,words', [
    ('latent_dim', 64, 'latent_dim must be config.obs_dim (39)'),
    ('normalize_dynamics', True, 'normalize_dynamics=False'),
    ('normalize_obs', False, 'normalize_obs=True'),
    ('encoder_type', 'cnn', "'mlp', 'identity' or 'conv'"),
    ('dynamics_type', 'mlp', 'does not go with dynamics_type=mlp'),
])
def test_inconsistent_settings_are_one_line(field, value, words):
  config = obs_space_config()
  config.model[field] = value
  with pytest.raises(ValueError, match=words.replace('(', r'\(').replace(')', r'\)')):
    validate_config(config)


def test_configs_saved_before_the_field_keep_the_learned_encoder():
  config = door_open.get_config('smoke')
  config.version = 5
  del config.model['encoder_type']
  from ld_mpc_jax.learn import checkpointing
  config = checkpointing.migrate_config(config.to_dict())  # As on load.
  assert config.model.encoder_type == 'mlp'
  nets = models.build_networks(ModelSettings.from_config(config))
  assert isinstance(nets.encoder, models.Encoder)
