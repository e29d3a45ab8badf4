"""Samplers against an analytic case: Gaussian data with its exact denoiser."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.ops import diffusion

MU = jnp.array([0.5, -0.3, 0.0])
STD = jnp.array([0.5, 0.2, 1.0])


def exact_model(prediction):
  """E[x0 | x_t] for x0 ~ N(MU, STD^2), as an x0- or eps-prediction."""
  def model_fn(x_t, t):
    ab = diffusion.alpha_bar(t)
    a, var_n = jnp.sqrt(ab), 1.0 - ab
    x0 = MU + a * STD ** 2 / (ab * STD ** 2 + var_n) * (x_t - a * MU)
    if prediction == 'x0':
      return x0
    return (x_t - a * x0) / jnp.sqrt(var_n)
  return model_fn


def test_alpha_bar_endpoints_and_monotone():
  t = jnp.linspace(0.0, 1.0, 101)
  ab = diffusion.alpha_bar(t)
  assert float(ab[0]) == pytest.approx(1.0)
  assert float(ab[-1]) == pytest.approx(diffusion.ALPHA_BAR_MIN)
  assert bool(jnp.all(jnp.diff(ab) <= 0))


def test_q_sample_matches_formula():
  x0, eps, t = jnp.ones((2, 3)), jnp.full((2, 3), 2.0), jnp.array([0.0, 0.5])
  ab = diffusion.alpha_bar(t)[:, None]
  np.testing.assert_allclose(diffusion.q_sample(x0, t, eps),
                             jnp.sqrt(ab) * x0 + jnp.sqrt(1 - ab) * eps, rtol=1e-6)
  np.testing.assert_allclose(diffusion.q_sample(x0, t, eps)[0], x0[0], rtol=1e-6)


def chain_moments(num_steps, eta):
  """Exact mean/variance after the discretised sampler chain with the exact denoiser.

  Every step is affine in x_t plus Gaussian noise, so the moments propagate in closed form.
  """
  m, v = jnp.zeros(3), jnp.ones(3)
  for i in range(num_steps):
    t, s = (num_steps - i) / num_steps, (num_steps - i - 1) / num_steps
    ab_t, ab_s = diffusion.alpha_bar(t), diffusion.alpha_bar(s)
    a_t, a_s, sig_t = jnp.sqrt(ab_t), jnp.sqrt(ab_s), jnp.sqrt(1 - ab_t)
    var = eta ** 2 * (1 - ab_s) / (1 - ab_t) * (1 - ab_t / ab_s)
    c1 = jnp.sqrt(jnp.maximum(1 - ab_s - var, 0.0)) / sig_t
    g = a_t * STD ** 2 / (ab_t * STD ** 2 + 1 - ab_t)  # x0_hat = g x_t + MU (1 - g a_t).
    gain, offset = (a_s - c1 * a_t) * g + c1, (a_s - c1 * a_t) * MU * (1 - g * a_t)
    m, v = gain * m + offset, gain ** 2 * v + var
  return m, jnp.sqrt(v)


def run_sampler(prediction, num_steps, eta, n=20_000):
  x_init = jax.random.normal(jax.random.key(0), (n, 3))
  return jax.jit(lambda x, k: diffusion.sample(exact_model(prediction), x, k, num_steps, eta,
                                               prediction))(x_init, jax.random.key(1))


@pytest.mark.parametrize('prediction', ['x0', 'eps'])
@pytest.mark.parametrize('num_steps,eta', [(32, 1.0), (8, 0.0), (32, 0.0)])
def test_sampler_matches_exact_chain_moments(prediction, num_steps, eta):
  """DDPM (eta=1) and DDIM (eta=0) produce exactly the moments of their discretised chains."""
  x = run_sampler(prediction, num_steps, eta)
  mean, std = chain_moments(num_steps, eta)
  np.testing.assert_allclose(x.mean(0), mean, atol=0.02)
  np.testing.assert_allclose(x.std(0), std, rtol=0.03)


@pytest.mark.parametrize('eta', [1.0, 0.0])
def test_sampler_converges_to_target(eta):
  """With enough steps both samplers recover the data distribution N(MU, STD^2)."""
  x = run_sampler('x0', 256, eta)
  np.testing.assert_allclose(x.mean(0), MU, atol=0.02)
  np.testing.assert_allclose(x.std(0), STD, rtol=0.05)
  # The exact chain converges too, and at 32 DDIM steps is within 12% of the target spread
  # (few-step first-order samplers shrink the variance; this bounds how much).
  np.testing.assert_allclose(chain_moments(256, eta)[1], STD, rtol=0.04)
  np.testing.assert_allclose(chain_moments(32, 0.0)[1], STD, rtol=0.12)


def test_sampler_detects_a_wrong_denoiser():
  """The check above can fail: a denoiser with the wrong variance gives the wrong spread."""
  def wrong(x_t, t):
    ab = diffusion.alpha_bar(t)
    a = jnp.sqrt(ab)
    return MU + a * (0.5 * STD) ** 2 / (ab * (0.5 * STD) ** 2 + 1 - ab) * (x_t - a * MU)
  x = diffusion.sample(wrong, jax.random.normal(jax.random.key(0), (20_000, 3)),
                       jax.random.key(1), 32, 1.0)
  assert not np.allclose(x.std(0), chain_moments(32, 1.0)[1], rtol=0.03)


def test_sampler_deterministic_for_key_and_clips():
  model_fn = lambda x, t: 3.0 * jnp.ones_like(x)  # Predicts x0 outside the box.
  x_init = jax.random.normal(jax.random.key(0), (5, 2))
  a = diffusion.sample(model_fn, x_init, jax.random.key(3), 4, 1.0, clip_x0=1.0)
  b = diffusion.sample(model_fn, x_init, jax.random.key(3), 4, 1.0, clip_x0=1.0)
  np.testing.assert_array_equal(a, b)
  np.testing.assert_allclose(a, 1.0, atol=1e-6)  # Last step returns the clipped x0.


def test_denoising_loss_is_zero_for_perfect_x0_model():
  x0 = jax.random.normal(jax.random.key(0), (16, 4))
  perfect = lambda x_t, t: x0
  np.testing.assert_allclose(diffusion.denoising_loss(perfect, x0, jax.random.key(1)), 0.0)
  zero = lambda x_t, t: jnp.zeros_like(x_t)
  np.testing.assert_allclose(diffusion.denoising_loss(zero, x0, jax.random.key(1)),
                             (x0 ** 2).mean(-1), rtol=1e-6)


def test_sample_rejects_bad_steps():
  with pytest.raises(ValueError, match='num_steps'):
    diffusion.sample(lambda x, t: x, jnp.zeros(2), jax.random.key(0), 0)
