"""MPPI: shapes and bounds, determinism, no recompilation, convergence on a toy objective, and the
elites and mean it returns on LD-MPC's world model checked against the values that model gave."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.model import tdmpc2_world
from ld_mpc_jax.plan import mppi
from ld_mpc_jax.model.models import count_params
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings

TINY_MODEL = tdmpc2_world.TDMPC2Config(latent_dim=16, enc_dim=16, mlp_dim=16, num_q=3, num_bins=11)
TINY_MPPI = mppi.MPPIConfig(num_samples=32, num_elites=8, num_prior=4, iterations=2)


@pytest.fixture(scope='module')
def tiny():
  params = tdmpc2_world.init_tdmpc2_params(TINY_MODEL, jax.random.key(0))
  z = tdmpc2_world.TDMPC2Model(TINY_MODEL).apply({'params': params}, jnp.linspace(-1, 1, 39),
                                          method=tdmpc2_world.TDMPC2Model.encode)
  return params, z


def test_shapes_bounds_and_determinism(tiny):
  params, z = tiny
  plan = mppi.make_tdmpc2_mppi(TINY_MPPI, TINY_MODEL)
  c = TINY_MPPI
  out = plan(params, z, jax.random.key(0))
  assert out.action.shape == (c.action_dim,)
  assert out.mean.shape == out.std.shape == (c.horizon, c.action_dim)
  assert out.elite_actions.shape == (c.num_elites, c.horizon, c.action_dim)
  assert out.elite_values.shape == (c.num_elites,)
  assert bool(jnp.all(jnp.abs(out.action) <= 1.0))
  assert bool(jnp.all(jnp.abs(out.elite_actions) <= 1.0))
  assert bool(jnp.all((out.std >= c.min_std - 1e-6) & (out.std <= c.max_std + 1e-6)))
  assert bool(jnp.all(jnp.isfinite(out.elite_values)))
  # The executed action is the first action of one of the elites.
  assert bool(jnp.any(jnp.all(out.elite_actions[:, 0] == out.action, axis=-1)))
  again = plan(params, z, jax.random.key(0))
  np.testing.assert_array_equal(out.action, again.action)
  np.testing.assert_array_equal(out.mean, again.mean)


def test_no_recompile_on_second_call(tiny):
  params, z = tiny
  plan = mppi.make_tdmpc2_mppi(TINY_MPPI, TINY_MODEL)
  out = plan(params, z, jax.random.key(0), jnp.zeros((3, 4)))
  plan(params, z + 0.1, jax.random.key(1), out.mean)
  assert plan._cache_size() == 1


def test_converges_to_optimum_of_toy_model():
  """value = -sum_t ||a_t - a*||^2: the refined mean must approach a* in every step."""
  target = jnp.array([0.5, -0.3, 0.2, -0.7])
  value_fn = lambda params, z, actions, key: -jnp.sum((actions - target) ** 2, axis=(1, 2))
  cfg = mppi.MPPIConfig(num_samples=256, num_elites=32, num_prior=0, iterations=8)
  out = mppi.make_mppi_plan(cfg, value_fn)({}, jnp.zeros((1,)), jax.random.key(0))
  np.testing.assert_allclose(out.mean, jnp.broadcast_to(target, out.mean.shape), atol=0.1)
  np.testing.assert_allclose(out.action, target, atol=0.2)


def test_prior_trajectories_are_candidates():
  """A prior that proposes the optimum exactly wins at once: one iteration, tiny spread."""
  target = jnp.array([0.9, -0.9, 0.0, 0.5])
  value_fn = lambda params, z, actions, key: -jnp.sum((actions - target) ** 2, axis=(1, 2))
  prior_fn = lambda params, z, key, num: jnp.broadcast_to(target, (num, 3, 4))
  cfg = mppi.MPPIConfig(num_samples=64, num_elites=4, num_prior=4, iterations=1,
                        temperature=100.0)
  out = mppi.make_mppi_plan(cfg, value_fn, prior_fn)({}, jnp.zeros((1,)), jax.random.key(0))
  np.testing.assert_allclose(out.action, target, atol=1e-6)
  with pytest.raises(ValueError, match='prior_fn'):
    mppi.make_mppi_plan(cfg, value_fn)


def test_config_validation():
  with pytest.raises(ValueError, match='num_elites'):
    mppi.MPPIConfig(num_samples=8, num_elites=16, num_prior=0)
  with pytest.raises(ValueError, match='num_prior'):
    mppi.MPPIConfig(num_samples=8, num_elites=4, num_prior=8)


def _mlp_size(d_in, widths):
  """Scalars of networks.MLP: Dense kernels and biases, LayerNorm scale and bias between."""
  dims = (d_in,) + tuple(widths)
  dense = sum(a * b + b for a, b in zip(dims[:-1], dims[1:]))
  return dense + sum(2 * w for w in widths[:-1])


def _tdmpc2_size(c):
  """TD-MPC2's world model, counted from its widths: encoder (+ LayerNorm), dynamics
  (+ LayerNorm), reward head, policy, num_q Q heads."""
  za, hidden = c.latent_dim + c.action_dim, (c.mlp_dim, c.mlp_dim)
  return (_mlp_size(c.obs_dim, (c.enc_dim, c.latent_dim)) + 2 * c.latent_dim
          + _mlp_size(za, hidden + (c.latent_dim,)) + 2 * c.latent_dim
          + _mlp_size(za, hidden + (c.num_bins,))
          + _mlp_size(c.latent_dim, hidden + (2 * c.action_dim,))
          + c.num_q * _mlp_size(za, hidden + (c.num_bins,)))


@pytest.mark.parametrize('cfg', [tdmpc2_world.TDMPC2Config(), TINY_MODEL], ids=['default', 'tiny'])
def test_tdmpc2_model_size(cfg):
  """The parameters are the layers the widths call for; the default is TD-MPC2's "5M"."""
  params = jax.eval_shape(lambda k: tdmpc2_world.init_tdmpc2_params(cfg, k), jax.random.key(0))
  assert count_params(params) == _tdmpc2_size(cfg)
  if cfg == tdmpc2_world.TDMPC2Config():
    assert 4.5e6 < count_params(params) < 5.5e6


def test_mppi_on_ldmpc_world_model(smoke_config, smoke_params):
  """On LD-MPC's diffusion dynamics and objective, the elites MPPI returns are the best-scored
  sequences of its last iteration, with the values the world model gave them, and its mean is
  their softmax-weighted average."""
  from ld_mpc_jax import encode
  c = smoke_config
  cfg = mppi.MPPIConfig(action_dim=c.action_dim, horizon=c.horizon, num_samples=8,
                        num_elites=2, num_prior=0, iterations=2, temperature=0.5)
  value_fn = mppi.make_ldmpc_value_fn(ModelSettings.from_config(c), PlanSettings.from_config(c))
  scored = []

  def recorded(params, z, actions, key):  # Every iteration's candidates and their values J.
    values = value_fn(params, z, actions, key)
    jax.debug.callback(lambda a, v: scored.append((np.asarray(a), np.asarray(v))), actions,
                       values, ordered=True)
    return values

  plan = mppi.make_mppi_plan(cfg, recorded)
  z = encode(smoke_params, np.linspace(-1, 1, 39).astype(np.float32))
  out = jax.device_get(plan(smoke_params, z, jax.random.key(0)))
  assert len(scored) == cfg.iterations
  actions, values = scored[-1]
  assert np.ptp(values) > 1e-3  # J tells the candidates apart.
  best = np.argsort(-values)[:cfg.num_elites]
  np.testing.assert_allclose(out.elite_values, values[best], rtol=1e-6)
  np.testing.assert_allclose(out.elite_actions, actions[best], rtol=1e-6)
  w = np.exp(cfg.temperature * (values[best] - values[best].max()))
  np.testing.assert_allclose(out.mean, np.tensordot(w / w.sum(), actions[best], axes=1),
                             rtol=1e-5, atol=1e-6)
  # The executed action is the first action of one of the elites.
  assert np.any(np.all(np.isclose(out.elite_actions[:, 0], out.action), axis=-1))
