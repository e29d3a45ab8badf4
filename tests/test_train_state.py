"""The jitted update: it lowers the joint loss, EMA math, shape checks, donation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax import LearnSettings, create_train_state, make_update
from ld_mpc_jax.learn.train_state import ema_update


def make_batch(config, batch_size=8, seed=0):
  rng = np.random.default_rng(seed)
  h = config.horizon
  return {
      'obs': rng.normal(size=(batch_size, h + 2, config.obs_dim)).astype(np.float32),
      'action': rng.uniform(-1, 1, size=(batch_size, h + 1, config.action_dim)).astype(
          np.float32),
      'reward': rng.uniform(0, 5, size=(batch_size, h + 1)).astype(np.float32),
  }


def test_ema_update_hand_values():
  ema = ema_update({'w': jnp.array([1.0, 2.0])}, {'w': jnp.array([3.0, -2.0])}, decay=0.9)
  np.testing.assert_allclose(ema['w'], [1.2, 1.6], rtol=1e-6)


@pytest.fixture
def fit_config(smoke_config):
  """The smoke config with a step size that fits a fixed batch in a few dozen updates. Every
  update test here uses this one config, so its update is compiled once per test session (the
  persistent compilation cache serves the rest)."""
  smoke_config.train.learning_rate = 3e-3
  smoke_config.model.dropout = 0.0
  return smoke_config


@pytest.fixture
def learn(fit_config):
  return LearnSettings.from_config(fit_config)


def test_learn_settings_hash_by_value(fit_config, learn):
  """Equal configs give equal settings, one key of the update's cache (ops.build_cache)."""
  again = LearnSettings.from_config(fit_config)
  assert again == learn and hash(again) == hash(learn)
  assert make_update(again) is make_update(learn)


def test_a_config_instead_of_its_settings_is_one_line_naming_the_fix(smoke_config):
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.learn.train_state import (  # pylint: disable=g-import-not-at-top
      make_multi_update, make_seeds_update)
  for name, build in (('make_update', make_update),
                      ('make_multi_update', lambda c: make_multi_update(c, 2)),
                      ('make_seeds_update', lambda c: make_seeds_update(c, 2)),
                      ('create_train_state', lambda c: create_train_state(c, jax.random.key(0))),
                      ('abstract_state', checkpointing.abstract_state)):
    with pytest.raises(TypeError) as err:
      build(smoke_config)
    assert str(err.value) == (f'{name} takes LearnSettings, not a ConfigDict: pass '
                              'LearnSettings.from_config(config)')


def test_update_lowers_loss_on_fixed_batch(fit_config, learn):
  state = create_train_state(learn, jax.random.key(0))
  update = make_update(learn)
  batch, key = make_batch(fit_config), jax.random.key(1)  # Same noise every step.
  losses = []
  for _ in range(40):
    state, metrics = update(state, batch, key)
    losses.append(float(metrics['loss']))
  assert all(np.isfinite(losses))
  assert losses[-1] < 0.6 * losses[0], losses
  assert int(state.step) == 40


def test_update_applies_ema_of_new_params(fit_config, learn):
  state = create_train_state(learn, jax.random.key(0))
  old_ema = jax.tree_util.tree_map(np.array, state.ema_params)  # Copies: the update donates.
  update = make_update(learn)
  state, _ = update(state, make_batch(fit_config), jax.random.key(1))
  params, ema = jax.device_get((state.params, state.ema_params))  # NumPy from here on.
  decay = fit_config.train.ema_decay
  expected = jax.tree_util.tree_map(lambda e, p: decay * e + (1 - decay) * p, old_ema, params)
  jax.tree_util.tree_map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-7),
                         ema, expected)
  # The parameters moved, so the EMA differs from both.
  moved = jax.tree_util.tree_leaves(jax.tree_util.tree_map(
      lambda a, b: float(np.max(np.abs(a - b))), params, old_ema))
  assert max(moved) > 0


def test_update_rejects_wrong_batch_shape(fit_config, learn):
  state = create_train_state(learn, jax.random.key(0))
  batch = make_batch(fit_config)
  batch['obs'] = batch['obs'][:, :-1]
  with pytest.raises(ValueError, match="batch\\['obs'\\]"):
    make_update(learn)(state, batch, jax.random.key(0))


def test_update_does_not_recompile(fit_config, learn):
  state = create_train_state(learn, jax.random.key(0))
  update = make_update(learn)  # Shared by every test of this config (build_cache).
  sizes = []
  for i in range(3):
    state, _ = update(state, make_batch(fit_config, seed=i), jax.random.key(i))
    sizes.append(update._cache_size())
  assert sizes[0] == sizes[-1] >= 1
