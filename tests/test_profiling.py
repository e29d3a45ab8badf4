"""ld_mpc_jax.bench.profiling: op classification, HLO parsing and a traced smoke plan."""

import jax
import jax.numpy as jnp
import pytest

from ld_mpc_jax.bench import profiling


@pytest.mark.parametrize('op_name,is_matmul,expected', [
    ('jit(plan)/while/body/closed_call/ActionProposal.denoise/backbone/block_2/mlp_in/'
     'dot_general', True, ('proposal', 'matmul')),
    ('jit(plan)/while/body/closed_call/while/body/closed_call/LatentDynamics.denoise/backbone/'
     'block_0/attn/add', False, ('dynamics', 'attention element-wise')),
    ('jit(plan)/SequenceObjective/backbone/block_3/ln_mlp/reduce_sum', False,
     ('objective', 'layernorm')),
    ('jit(plan)/while/body/closed_call/ActionProposal.denoise/backbone/block_1/mul', False,
     ('proposal', 'mlp element-wise (GELU, residual)')),
    ('jit(plan)/while/body/jit(_normal)/jit(_normal_real)/jit(_uniform)/shift_right_logical',
     False, ('other', 'random numbers')),
    ('jit(plan)/argmax', False, ('other', 'other')),
])
def test_classify(op_name, is_matmul, expected):
  assert profiling.classify(op_name, is_matmul) == expected


def test_hlo_ops_marks_matrix_products_only():
  f = jax.jit(lambda a, b: jnp.tanh(a @ b).sum(axis=-1))
  a = jnp.ones((32, 64))
  ops = profiling.hlo_ops(f.lower(a, a.T).compile().as_text())
  matmuls = [name for name, (op_name, mm) in ops.items() if mm]
  assert matmuls and all('dot_general' in ops[n][0] for n in matmuls)
  assert any(not mm for _, mm in ops.values())  # the reduction is not counted as a matmul


def test_profile_smoke_plan_finds_the_matmuls(smoke_config):
  result = profiling.profile_plan(smoke_config, calls=1)
  kinds = {key.split('/')[1] for key in result['ms_per_call']}
  assert kinds <= set(profiling.KINDS)
  networks = {key.split('/')[0] for key in result['ms_per_call']}
  assert {'proposal', 'dynamics', 'objective'} <= networks
  assert result['ms_per_call'].get('dynamics/matmul', 0) > 0
  assert result['ops_ms'] == pytest.approx(sum(result['ms_per_call'].values()))
  assert '| matmul |' in profiling.markdown(result)
  assert result['op_events_per_call'] >= result['short_op_events_per_call'] > 0
  # Each thread is busy at most the wall time of the traced calls and at least one is busy.
  assert 0 < max(result['thread_busy_ms']) <= result['ops_ms'] + result['unmatched_ms'] + 1e-6


def test_busy_time_is_the_union_of_intervals():
  assert profiling._busy_us([(0, 10), (5, 12), (20, 25), (21, 22)]) == 17
  assert profiling._busy_us([]) == 0


def test_profile_smoke_update_finds_every_network(smoke_config):
  result = profiling.profile_update(smoke_config, calls=1)
  networks = {key.split('/')[0] for key in result['ms_per_call']}
  assert {'encoder', 'proposal', 'dynamics', 'objective', 'critics', 'actor'} <= networks
  assert result['ms_per_call'].get('critics/matmul', 0) > 0
  assert result['wall_ms_median'] > 0
