"""ld_mpc_jax.nets.mlp: mish against jax's, and the MLP's layers against their formula."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.nets.mlp import MLP, mish


def test_mish_is_jax_mish_with_its_gradient():
  x = jnp.concatenate([jnp.linspace(-60.0, 60.0, 12001), jnp.array([-1e4, 0.0, 1e4])])
  np.testing.assert_allclose(mish(x), jax.nn.mish(x), rtol=1e-6, atol=1e-6)
  grad = lambda f: jax.vmap(jax.grad(f))(x)
  np.testing.assert_allclose(grad(mish), grad(jax.nn.mish), rtol=1e-4, atol=1e-5)
  assert float(mish(jnp.array(1.0))) == pytest.approx(0.865098, abs=1e-5)


@pytest.mark.parametrize('activate_final', [False, True])
def test_mlp_is_dense_layernorm_mish_between_layers(activate_final):
  mlp = MLP((5, 3), activate_final=activate_final)
  x = jax.random.normal(jax.random.key(0), (4, 2))
  params = mlp.init(jax.random.key(1), x)['params']
  assert set(params) == {'dense_0', 'norm_0', 'dense_1'} | ({'norm_1'} if activate_final else set())

  def dense(p, h):
    return h @ np.asarray(p['kernel']) + np.asarray(p['bias'])

  def norm_mish(p, h):  # LayerNorm (epsilon 1e-6, as flax's), then x tanh(softplus(x)).
    h = (h - h.mean(-1, keepdims=True)) / np.sqrt(h.var(-1, keepdims=True) + 1e-6)
    h = h * np.asarray(p['scale']) + np.asarray(p['bias'])
    return h * np.tanh(np.log1p(np.exp(h)))

  want = dense(params['dense_1'], norm_mish(params['norm_0'], dense(params['dense_0'],
                                                                      np.asarray(x))))
  if activate_final:
    want = norm_mish(params['norm_1'], want)
  np.testing.assert_allclose(mlp.apply({'params': params}, x), want, rtol=1e-4, atol=1e-5)
