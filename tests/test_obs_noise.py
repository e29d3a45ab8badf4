"""Observation noise (issue 71): constant features masked out of the encoder's input, noise only
where configured (evaluation, or training with augmentation), the model's latent filter, and
the sweep's table."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.analysis import noise_sweep
from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.learn import losses
from ld_mpc_jax.model import models
from ld_mpc_jax.plan.agent import make_act, uses_prev
from ld_mpc_jax.model.settings import LossSettings, ModelSettings, PlanSettings
from ld_mpc_jax.plan.modes import ActSettings

CONSTANT = (5, 11, 12)  # Features constant in the toy data below.


def _data(obs_dim=39, n=400):
  obs = np.random.default_rng(0).normal(0.5, 0.2, size=(n, obs_dim)).astype(np.float32)
  obs[:, list(CONSTANT)] = 0.25
  return obs


def test_constant_features_are_masked_out_of_the_encoders_input(smoke_config):
  obs = _data()
  params = models.init_params(smoke_config, jax.random.key(0))
  masked = models.set_obs_normalization(params, obs, mask_constant=True)
  floored = models.set_obs_normalization(params, obs)
  std = np.asarray(masked['encoder']['obs_std'])
  assert np.all(std[list(CONSTANT)] == models.MASKED_OBS_STD)
  np.testing.assert_allclose(std[0], obs[:, 0].std(), rtol=1e-4)  # The others: as before.
  np.testing.assert_allclose(np.delete(std, CONSTANT),
                             np.delete(np.asarray(floored['encoder']['obs_std']), CONSTANT))
  noise = np.zeros_like(obs[:8])
  noise[:, list(CONSTANT)] = 0.01  # 1 cm on the constant features only.
  clean = np.asarray(models.encode(masked, obs[:8]))
  np.testing.assert_allclose(models.encode(masked, obs[:8] + noise), clean, atol=1e-5)
  # With the old floor the same noise is a unit-variance input: the latent moves.
  moved = np.abs(models.encode(floored, obs[:8] + noise) - models.encode(floored, obs[:8]))
  assert moved.max() > 1e-2
  informative = models.informative_dims(masked)
  assert not informative[list(CONSTANT)].any() and informative.sum() == 39 - len(CONSTANT)
  # Parameters saved before the mask: the features at the floor are the uninformative ones.
  np.testing.assert_array_equal(models.informative_dims(floored), informative)


def test_evaluation_noise_only_where_configured(smoke_config):
  params = models.set_obs_normalization(
      models.init_params(smoke_config, jax.random.key(0)), _data(), mask_constant=True)
  spec = EvalSpec.from_config(smoke_config)
  assert evaluation_suite.noise_stds(spec, params, None) == 0.0  # The protocol.
  c = with_overrides(smoke_config, {'eval.obs_noise': 0.02})
  spec = EvalSpec.from_config(c)
  assert evaluation_suite.noise_stds(spec, params, None) == 0.02  # Every dimension.
  assert evaluation_suite.noise_stds(spec, params, 0.05) == 0.05  # An explicit std wins.
  spec = EvalSpec.from_config(with_overrides(c, {'eval.obs_noise_dims': 'informative'}))
  per_dim = evaluation_suite.noise_stds(spec, params, None)
  assert per_dim.shape == (39,) and np.all(per_dim[list(CONSTANT)] == 0)
  assert np.all(np.delete(per_dim, CONSTANT) == 0.02)
  del params['encoder']['obs_std']
  with pytest.raises(ValueError, match='normalize_obs'):
    evaluation_suite.noise_stds(spec, params, None)


def test_environment_adds_per_dimension_noise_seeded_per_episode():
  from ld_mpc_jax.envs import metaworld_env
  std = np.zeros(39)
  std[:3] = 0.05  # The hand's position only.
  clean, _ = metaworld_env.make_env('door-open-v3', seed=0).reset(seed=3)
  noisy_env = metaworld_env.make_env('door-open-v3', seed=0, obs_noise_std=std)
  noisy, _ = noisy_env.reset(seed=3)
  assert np.all(noisy[3:] == clean[3:]) and np.abs(noisy[:3] - clean[:3]).min() > 0
  again, _ = noisy_env.reset(seed=3)
  np.testing.assert_array_equal(again, noisy)  # The same episode, the same noise.
  with pytest.raises(ValueError, match='obs_noise_std'):
    metaworld_env.make_env('door-open-v3', seed=0, obs_noise_std=-std)


def _batch(h, rng):
  return {'obs': jnp.asarray(rng.normal(size=(2, h + 2, 39)), jnp.float32),
          'action': jnp.asarray(rng.uniform(-1, 1, (2, h + 1, 4)), jnp.float32),
          'reward': jnp.asarray(rng.uniform(0, 1, (2, h + 1)), jnp.float32)}


def test_training_noise_only_with_augmentation(smoke_config):
  batch = _batch(smoke_config.horizon, np.random.default_rng(0))
  params = models.init_params(smoke_config, jax.random.key(0))
  out = {}
  for aug in (0.0, 0.1):
    c = with_overrides(smoke_config, {'train.obs_noise_aug': aug, 'critic.value': 'behaviour',
                                      'critic.actor': 'bc', 'critic.latent_rollout': False})
    m = ModelSettings.from_config(c)
    loss_fn = jax.jit(losses.make_loss_fn(m, LossSettings.from_config(c),
                                          models.build_networks(m)))
    out[aug] = loss_fn(params, params, batch, jax.random.key(1))[1]
  assert 'loss_noise_inv' not in out[0.0]
  assert float(out[0.1]['loss_noise_inv']) > 0  # A noisy latent away from the clean one.
  assert float(out[0.1]['loss_dyn']) != float(out[0.0]['loss_dyn'])  # Models see the noise.
  # The value targets come from the clean observations' EMA latents: unchanged.
  np.testing.assert_allclose(out[0.1]['value_target_mean'], out[0.0]['value_target_mean'],
                             rtol=1e-6)


@pytest.mark.parametrize('mode', ['actor', 'plan'])
def test_latent_filter_blends_the_models_prediction(smoke_config, smoke_params, mode):
  obs = np.linspace(-1, 1, 39).astype(np.float32)
  key = jax.random.key(0)
  plain = make_act(ActSettings.from_config(smoke_config), mode)
  c = with_overrides(smoke_config, {'plan.latent_filter': 0.5})
  assert uses_prev(PlanSettings.from_config(c), mode)
  assert not uses_prev(PlanSettings.from_config(smoke_config), 'actor')
  filt = make_act(ActSettings.from_config(c), mode)
  a0, carry, _ = filt(smoke_params, obs, key, 0, None)
  np.testing.assert_allclose(a0, plain(smoke_params, obs, key, 0, None)[0], atol=1e-6)
  _, z0, a_exec = carry  # (the mode's own carry, the latent acted on, the executed action)
  np.testing.assert_allclose(z0, models.encode(smoke_params, obs), atol=1e-6)
  np.testing.assert_allclose(a_exec, a0)
  a1, (_, z1, _), _ = filt(smoke_params, obs, key, 1, carry)
  z_obs = np.asarray(models.encode(smoke_params, obs))
  assert np.abs(z1 - z_obs).max() > 1e-3  # The prediction moved the latent,
  np.testing.assert_allclose(np.sqrt(np.mean(np.asarray(z1) ** 2)), 1.0, rtol=1e-3)  # On the sphere.
  if mode == 'actor':  # The actor acts on the filtered latent.
    nets = models.build_networks(ModelSettings.from_config(c))
    want = nets.actor.apply({'params': smoke_params['actor']}, z1)
    np.testing.assert_allclose(a1, want, atol=1e-5)


def test_noise_table_pairs_policies_and_compares_with_clean():
  records = []
  for std, plan_wins, actor_wins in ((0.0, 10, 10), (0.01, 9, 6)):
    for i in range(10):
      records.append(dict(obs_noise=std, policy='plan', success=int(i < plan_wins), run=0,
                          split='held_out', eval_seed=0, episode=i))
      records.append(dict(obs_noise=std, policy='actor', success=int(i < actor_wins), run=0,
                          split='held_out', eval_seed=0, episode=i))
  rows = {(r['obs_noise'], r['policy']): r for r in noise_sweep.table(records)}
  assert rows[(0.01, 'plan')]['of_clean'] == pytest.approx(0.9)
  assert rows[(0.01, 'actor')]['of_clean'] == pytest.approx(0.6)
  test = rows[(0.01, 'actor')]['vs_plan']
  assert (test['a_only'], test['b_only']) == (3, 0) and rows[(0.01, 'plan')]['vs_plan'] is None
  md = noise_sweep.markdown(list(rows.values()))
  assert '| 0.01 | actor prior | 6/10 = 0.60 |' in md and '3 / 0' in md
