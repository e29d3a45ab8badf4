"""benchmarks.profiling: a compiled program of known parts classified, HLO parsing and a traced
smoke plan."""

import jax
import jax.numpy as jnp
import pytest

from benchmarks import profiling


def _known_program(x, w, key):
  """A program whose parts sit where the networks' do: a proposal block (matmul, attention
  element-wise, LayerNorm, MLP element-wise) and dynamics noise (random numbers)."""
  with jax.named_scope('ActionProposal.denoise'), jax.named_scope('backbone'):
    with jax.named_scope('block_0'):
      with jax.named_scope('attn'):
        h = jnp.tanh(x @ w)
      with jax.named_scope('ln_mlp'):
        h = h - h.mean(-1, keepdims=True)
    with jax.named_scope('block_1'):
      h = h * 3.0
  with jax.named_scope('LatentDynamics.denoise'):
    h = h + jax.random.normal(key, h.shape)
  return jnp.argmax(h, -1)


def test_compiled_known_program_is_classified_by_network_and_kind():
  x, w = jnp.ones((8, 16)), jnp.ones((16, 16))
  text = jax.jit(_known_program).lower(x, w, jax.random.key(0)).compile().as_text()
  got = {}
  for op_name, is_matmul in profiling.hlo_ops(text).values():
    got.setdefault(profiling.classify(op_name, is_matmul), []).append(op_name)
  assert {('proposal', 'matmul'), ('proposal', 'attention element-wise'),
          ('proposal', 'layernorm'), ('proposal', 'mlp element-wise (GELU, residual)'),
          ('dynamics', 'random numbers')} <= set(got)
  # The one matrix product is the proposal's, and it is the only matmul.
  matmuls = [n for (net, kind), names in got.items() if kind == 'matmul' for n in names]
  assert matmuls and all('ActionProposal' in n and 'dot_general' in n for n in matmuls)
  # Nothing outside a network's scope is given to a network.
  for (net, _), names in got.items():
    assert net == 'other' or all(('ActionProposal' if net == 'proposal' else 'LatentDynamics')
                                 in n for n in names), (net, names)


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


# Marked long: benchmark tooling that compiles and traces the whole update.
@pytest.mark.long
def test_profile_smoke_update_finds_every_network(smoke_config):
  result = profiling.profile_update(smoke_config, calls=1)
  networks = {key.split('/')[0] for key in result['ms_per_call']}
  assert {'encoder', 'proposal', 'dynamics', 'objective', 'critics', 'actor'} <= networks
  assert result['ms_per_call'].get('critics/matmul', 0) > 0
  assert result['wall_ms_median'] > 0
