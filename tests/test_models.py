"""Networks: shapes, the encoder's normalisation, the objective's causality, clear errors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax import count_params, encode, init_params
from ld_mpc_jax.model import models
from ld_mpc_jax.model.models import build_networks
from ld_mpc_jax.nets import fourier_features
from ld_mpc_jax.model.settings import ModelSettings


def test_fourier_features_hand_values():
  f = fourier_features(jnp.array([0.0, 1.0]), 4, max_period=100.0)
  # Frequencies 1 and 1/10: [cos(x), cos(x/10), sin(x), sin(x/10)].
  np.testing.assert_allclose(f[0], [1, 1, 0, 0], atol=1e-6)
  np.testing.assert_allclose(f[1], [np.cos(1), np.cos(0.1), np.sin(1), np.sin(0.1)], rtol=1e-5)
  with pytest.raises(ValueError, match='even'):
    fourier_features(jnp.zeros(1), 3)


def test_encode_single_and_batch(smoke_config, smoke_params):
  d = smoke_config.model.latent_dim
  z1 = encode(smoke_params, np.ones(39, np.float32))
  zb = encode(smoke_params, np.ones((2, 3, 39), np.float32))
  assert z1.shape == (d,) and zb.shape == (2, 3, d)
  np.testing.assert_allclose(zb[1, 2], z1, rtol=1e-4, atol=1e-6)
  np.testing.assert_allclose(jnp.mean(zb ** 2, -1), 1.0, rtol=1e-3)  # RMS-normalised.


@pytest.mark.parametrize('shape', [(38,), (2, 40), ()])
def test_encode_rejects_wrong_obs_size(smoke_params, shape):
  with pytest.raises(ValueError, match='39'):
    encode(smoke_params, np.zeros(shape, np.float32))


def test_network_output_shapes(smoke_config, smoke_params):
  nets = build_networks(ModelSettings.from_config(smoke_config))
  c = smoke_config
  b, h, d, a = 3, c.horizon, c.model.latent_dim, c.action_dim
  z = jnp.ones((b, d))
  shape = lambda f: jax.eval_shape(f).shape  # Traced, not compiled.
  out = shape(lambda: nets.proposal.apply({'params': smoke_params['proposal']},
                                          jnp.ones((b, h, a)), jnp.full((b,), 0.5), z))
  assert out == (b, h, a)
  out = shape(lambda: nets.dynamics.apply({'params': smoke_params['dynamics']}, z,
                                          jnp.array(0.3), z, jnp.ones((b, a))))
  assert out == (b, d)
  r, v = jax.eval_shape(lambda: nets.objective.apply({'params': smoke_params['objective']},
                                                     jnp.ones((b, h + 1, d)), jnp.ones((b, h, a))))
  assert r.shape == (b, h, c.model.num_bins) and v.shape == (b, h + 1, c.model.num_bins)
  pi = nets.actor.apply({'params': smoke_params['actor']}, 10 * z)
  assert pi.shape == (b, a) and bool(jnp.all(jnp.abs(pi) <= 1))


def test_objective_is_causal(smoke_config, smoke_params):
  """Rewards and earlier values never see later tokens; the last value does."""
  nets = build_networks(ModelSettings.from_config(smoke_config))
  h, d, a = smoke_config.horizon, smoke_config.model.latent_dim, smoke_config.action_dim
  z = jax.random.normal(jax.random.key(0), (h + 1, d))
  act = jax.random.uniform(jax.random.key(1), (h, a), minval=-1, maxval=1)
  apply = lambda z, act: nets.objective.apply({'params': smoke_params['objective']}, z, act)
  r0, v0 = apply(z, act)
  r1, v1 = apply(z.at[-1].add(5.0), act)
  np.testing.assert_allclose(r1, r0, rtol=1e-5, atol=1e-5)
  np.testing.assert_allclose(v1[:-1], v0[:-1], rtol=1e-5, atol=1e-5)
  assert not np.allclose(v1[-1], v0[-1])
  r2, _ = apply(z, act.at[1].add(0.5))
  np.testing.assert_allclose(r2[0], r0[0], rtol=1e-5, atol=1e-5)
  assert not np.allclose(r2[1], r0[1])


def test_reference_config_builds_with_expected_sizes():
  from ld_mpc_jax.configs import door_open
  c = door_open.get_config()
  params = jax.eval_shape(lambda k: init_params(c, k), jax.random.key(0))
  assert params['encoder']['mlp']['dense_0']['kernel'].shape == (39, 256)
  assert params['encoder']['mlp']['dense_1']['kernel'].shape == (256, 512)
  blocks = lambda tree: sum(k.startswith('block_') for k in tree['backbone'])
  assert blocks(params['dynamics']) == 5 and blocks(params['objective']) == 10
  assert 5_000_000 < count_params(params) < 30_000_000


def test_observation_normalisation_is_stored_in_the_parameters(smoke_config):
  obs = np.random.default_rng(0).normal(3.0, 2.0, size=(500, smoke_config.obs_dim))
  obs[:, 5] = 0.25  # A constant feature is only centred.
  params = models.set_obs_normalization(models.init_params(smoke_config, jax.random.key(0)),
                                        obs)
  np.testing.assert_allclose(params['encoder']['obs_mean'], obs.mean(0), rtol=1e-4)
  assert float(params['encoder']['obs_std'][5]) == pytest.approx(models.OBS_STD_FLOOR)
  plain = dict(params['encoder'])
  mean, std = plain.pop('obs_mean'), plain.pop('obs_std')
  enc = models.Encoder(smoke_config.model.encoder_hidden, smoke_config.model.latent_dim)
  np.testing.assert_allclose(models.encode(params, obs[:4]),
                             enc.apply({'params': plain}, (obs[:4] - mean) / std),
                             rtol=1e-4, atol=1e-5)
