"""FLOP counts: hand-computed layer counts, and the analytic count against XLA's corrected count."""

import flax.linen as nn
import jax
import jax.numpy as jnp
import pytest

from ld_mpc_jax.model import tdmpc2_world
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.plan import mppi
from benchmarks import flops
from ld_mpc_jax.nets import TransformerBlock


def test_dense_and_attention_hand_counts():
  # [2, 3] x [3, 5] + bias: 2 rows x (2 * 3 * 5 multiply-adds + 5 bias adds).
  assert flops.dense_flops(3, 5, rows=2) == 70
  assert flops.dense_flops(3, 5, rows=2, bias=False) == 60
  # L = 3, W = 8: Q K^T and P V are 9 x 8 multiply-adds each.
  assert flops.attention_flops(3, 8) == 2 * 2 * 9 * 8
  # L = 2, W = 4, MLP ratio 2, one sequence:
  #   QKV + out projections 4 x 2 tokens x (2*4*4 + 4) = 288; attention 2 x 2 x 4 x 4 = 64;
  #   MLP 2 x (2*4*8 + 8) + 2 x (2*8*4 + 4) = 144 + 136 = 280.
  assert flops.transformer_block_flops(2, 4, 2) == 288 + 64 + 280
  assert flops.transformer_flops(3, 2, 4, 2, rows=5) == 3 * 5 * 632
  # Last block computing 1 of the 2 tokens: QKV on both (3 x 2 x 36), output projection,
  # attention (2 x 2 x 1 x 2 x 4) and MLP (280 / 2) on one.
  assert flops.transformer_block_flops(2, 4, 2, outputs=1) == 216 + 36 + 32 + 140
  assert flops.transformer_flops(3, 2, 4, 2, outputs=1) == 2 * 632 + 424
  assert flops.mlp_flops((3, 5, 2)) == 2 * 3 * 5 + 5 + 2 * 5 * 2 + 2


def test_dense_hand_count_equals_xla():
  layer = nn.Dense(48)
  x = jnp.ones((10, 32))
  params = layer.init(jax.random.key(0), x)
  assert flops.xla_flops(layer.apply, params, x) == flops.dense_flops(32, 48, rows=10)


@pytest.mark.parametrize('outputs', [None, slice(1, None), slice(4, None)])
def test_transformer_block_hand_count_close_to_xla(outputs):
  block = TransformerBlock(num_heads=4)
  x = jnp.ones((8, 5, 64))
  params = block.init(jax.random.key(0), x)
  n_out = None if outputs is None else len(range(5)[outputs])
  hand = flops.transformer_block_flops(5, 64, 4, rows=8, outputs=n_out)
  xla = flops.xla_flops(lambda p, x: block.apply(p, x, outputs=outputs), params, x)
  assert hand <= xla <= 1.1 * hand  # XLA adds LayerNorm, GELU and softmax.


@pytest.fixture
def small_config(smoke_config):
  # Width 64 so that matrix products dominate the element-wise work the hand count leaves out.
  c = smoke_config
  c.model.width = c.model.latent_dim = 64
  c.model.num_heads = 4
  c.model.actor_hidden = (32,)
  c.plan.num_prior_candidates = 1
  return c


# Marked long: benchmark tooling on a whole compiled program (about 13 s each on a quiet core).
@pytest.mark.long
def test_plan_hand_count_matches_corrected_xla(small_config):
  settings = lambda c: (ModelSettings.from_config(c), PlanSettings.from_config(c))
  hand = flops.plan_flops(*settings(small_config))
  assert hand['total'] == (hand['proposal'] + hand['dynamics'] + hand['objective']
                           + hand['actor'])
  xla = flops.xla_plan_flops(*settings(small_config))
  assert abs(xla['total'] / hand['total'] - 1) < 0.1
  # The uncorrected cost analysis misses most denoising steps (scan bodies counted once).
  small_config.plan.action_steps = 6
  small_config.plan.dynamics_steps = 5
  xla6 = flops.xla_plan_flops(*settings(small_config))
  hand6 = flops.plan_flops(*settings(small_config))
  assert abs(xla6['total'] / hand6['total'] - 1) < 0.1
  assert xla6['plan_once'] < 0.6 * xla6['total']


@pytest.mark.long
def test_mppi_hand_count_matches_corrected_xla():
  # Width 128: LayerNorm, Mish and SimNorm (not in the hand count) stay below 10%.
  model_cfg = tdmpc2_world.TDMPC2Config(latent_dim=128, enc_dim=32, mlp_dim=128, num_q=3, num_bins=11)
  mppi_cfg = mppi.MPPIConfig(num_samples=32, num_elites=4, num_prior=4, iterations=3)
  params = tdmpc2_world.init_tdmpc2_params(model_cfg, jax.random.key(0))
  plan = mppi.make_tdmpc2_mppi(mppi_cfg, model_cfg)
  args = (params, jnp.zeros((128,)), jax.random.key(1))
  xla = flops.xla_mppi_flops(plan, args, mppi.make_tdmpc2_value_fn(model_cfg), params, mppi_cfg)
  hand = flops.tdmpc2_mppi_flops(mppi_cfg, model_cfg)
  assert abs(xla['total'] / hand['total'] - 1) < 0.1
