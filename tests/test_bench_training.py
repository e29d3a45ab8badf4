"""Training benchmark: FLOPs with scans unrolled (hand-checked). (The launchers:
tests/e2e/test_bench_launchers.py.)"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks import training


def _scans(x, w):
  """A scan of 5 steps [8, 16] @ [16, 16], each with a reversed inner scan of 3 such steps."""
  def inner(c, _):
    return c @ w, None

  def outer(c, y):
    c, _ = jax.lax.scan(inner, c + y, None, length=3, reverse=True)
    return c, c.sum()
  return jax.lax.scan(outer, x, jnp.ones((5,) + x.shape))


def test_unrolled_flops_count_every_iteration_and_keep_values():
  x, w = jnp.ones((8, 16)), jnp.eye(16) * 0.5
  matmul = 2 * 8 * 16 * 16  # One [8, 16] @ [16, 16]: 4096 FLOPs.
  out = training.unrolled_flops(_scans, x, w)
  # 5 x 3 = 15 matmuls; the element-wise adds and sums (5 x 2 x 128) are 2% of that.
  assert 15 * matmul <= out['total'] <= 15 * matmul + 5 * 2 * 128
  assert out['xla_once'] < 1.1 * matmul  # Compiled: each loop body counted once.
  # The unrolled program computes what the scanned one does, gradients (backward scans) too.
  loss = lambda x, w: _scans(x, w)[1].sum()
  for fn in (_scans, jax.grad(loss, argnums=1)):
    closed = jax.make_jaxpr(fn)(x, w)
    got = training._eval_unrolled(closed.jaxpr, closed.consts, x, w)
    for a, b in zip(got, jax.tree_util.tree_leaves(fn(x, w))):
      np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-6)
  grad = training.unrolled_flops(jax.grad(loss, argnums=1), x, w)
  # 15 products forward, 15 backward for dL/dw and 14 for dL/dcarry (none into x, not
  # differentiated), plus a few thousand element-wise FLOPs.
  assert 44 * matmul <= grad['total'] <= 44 * matmul + 2000


def test_scan_layout_read_off_shapes_matches_jax_counts():
  """JAX 0.11 dropped num_consts/num_carry from scan's params: the shapes give the same counts."""
  def f(w, c, xs):
    def body(carry, x):
      a, b = carry
      return (a * w + x[0], b + x[1].sum()), a * x[1]
    return jax.lax.scan(body, c, xs)
  args = (jnp.ones(3), (jnp.ones(3), jnp.zeros(())), (jnp.ones((5, 3)), jnp.ones((5, 3))))
  eqn = next(e for e in jax.make_jaxpr(f)(*args).jaxpr.eqns if e.primitive.name == 'scan')
  body = getattr(eqn.params['jaxpr'], 'jaxpr', eqn.params['jaxpr'])
  newer = type('Eqn', (), dict(params={k: v for k, v in eqn.params.items()
                                       if k not in ('num_consts', 'num_carry')},
                               invars=eqn.invars, outvars=eqn.outvars))
  assert training._scan_layout(newer, body) == (len(eqn.invars) - 4, 2)
  if 'num_consts' in eqn.params:  # This JAX also says so itself.
    assert training._scan_layout(eqn, body) == (eqn.params['num_consts'], 2)


def test_finish_bound_ratio():
  entry = training.finish(dict(step_s=[0.03, 0.01, 0.02], gflop=2.0, devices=2), 100.0)
  assert entry['step_ms'] == dict(median=20.0, min=10.0, max=30.0, n=3)
  # FLOP-bound time: 2 GFLOP / (100 GFLOP/s x 2 devices) = 10 ms; measured 20 ms.
  np.testing.assert_allclose(entry['bound_ratio'], 2.0)
  np.testing.assert_allclose(entry['achieved_gflops'], 100.0)


@pytest.mark.long  # Benchmark tooling on a whole compiled online run (about 20-40 s).
def test_online_breakdown_parts_add_up_to_the_timed_waves():
  """benchmarks.online_breakdown on the :smoke online preset, one timed wave: every part took
  time, the parts (host = the rest) add up to the wall time, and the counts are the wave's."""
  from benchmarks import online_breakdown
  from ld_mpc_jax.configs import door_open_online
  config = door_open_online.get_config('smoke')
  o = config.online
  e = online_breakdown.breakdown(config, num_seeds=1, waves=1)
  assert e['sim_steps'] == o.num_envs * o.episode_steps
  assert e['decisions'] == e['sim_steps'] // config.eval.action_repeat  # One per environment.
  assert e['updates'] == int(o.update_ratio * e['sim_steps'])
  ms = e['ms_per_sim_step']
  assert set(ms) == set(online_breakdown.PARTS)
  assert all(ms[p] > 0 for p in ('environments', 'plan', 'update', 'buffer sampling'))
  np.testing.assert_allclose(sum(ms.values()) * e['sim_steps'] / 1e3, e['wall_s'], rtol=1e-6)
  assert 0 < e['share']['update'] < 1


def test_online_seeds_variants_run_after_the_base_with_their_fields(monkeypatch):
  """--online_variant: each setting runs as given ('base'), then with each variant's fields;
  the rate against the base is taken within the same setting."""
  from benchmarks import online_seeds
  from ld_mpc_jax.configs import door_open_online
  seen = []

  def fake_run(c, overlap, skip):  # Steps/s that halve per seed and double with half the updates.
    seen.append((c.train.num_seeds, c.online.update_ratio))
    return 1.0, [40.0 / c.train.num_seeds * (0.5 / c.online.update_ratio)] * 3
  monkeypatch.setattr(online_seeds, '_run', fake_run)
  config = door_open_online.get_config('smoke')
  out = online_seeds.benchmark_seeds(config, [1, 3], 100,
                                     variants=[('half', {'online.update_ratio': 0.25})])
  r = config.online.update_ratio
  assert seen == [(1, r), (1, 0.25), (3, r), (3, 0.25)]
  assert [e['variant'] for e in out] == ['base', 'half', 'base', 'half']
  speed = (0.5 / 0.25) / (0.5 / r)
  np.testing.assert_allclose([e['rate_vs_base'] for e in out], [1, speed, 1, speed])
  np.testing.assert_allclose(out[3]['env_steps_per_s_all_seeds'], 40 * 0.5 / 0.25)
  assert config.online.update_ratio == r  # The given config is not changed.
  md = online_seeds.markdown(out, 'door_open_online.py:smoke', 100, 'cpu')
  assert md.splitlines()[-1].startswith('| half | 3 |')


def test_update_split_takes_each_part_against_the_update_as_configured():
  """Each part's saving is the base count minus the count with its fields set (a stub count
  that reads the fields: every part leaves out a known amount)."""
  from benchmarks import update_split
  from ld_mpc_jax.configs import door_open_online
  config = door_open_online.get_config('smoke')

  def gflop(c):
    return (10.0 - 4.0 * (not c.critic.latent_rollout) - 2.0 * (c.loss.w_dyn == 0)
            - 1.0 * (c.loss.w_act == 0) - 0.5 * (c.critic.num_values == 2)
            - 5.0 * (c.train.batch_size < config.train.batch_size))
  entries = update_split.split(config, gflop)
  saved = {e['part']: e['saved_gflop'] for e in entries}
  assert saved == dict(all=0.0, latent_rollout=4.0, dynamics_loss=2.0, proposal_loss=1.0,
                       values_3_to_5=0.5, half_batch=5.0)
  assert entries[1]['share'] == pytest.approx(0.4)
  assert entries[-1]['fields'] == {'train.batch_size': config.train.batch_size // 2}
  assert '| latent_rollout (' in update_split.markdown(entries, 'x.py:smoke')
  with pytest.raises(ValueError, match='unknown update parts'):
    update_split.split(config, gflop, parts=('nothing',))


def test_another_preset_of_the_same_file_is_a_variant_of_the_first():
  """`--online_seeds --configs=A,B`: B's fields that differ from A's, set on A, give B."""
  from benchmarks import online_seeds
  from ld_mpc_jax.configs import door_open_online
  from ld_mpc_jax.configs.overrides import with_overrides
  cpu, control = (door_open_online.get_config(p) for p in ('cpu', 'tdmpc2_cpu'))
  fields = online_seeds.fields_differing(cpu, control)
  assert fields['model.dynamics_type'] == 'mlp' and 'online.num_envs' not in fields
  assert with_overrides(cpu, fields).to_dict() == control.to_dict()
  assert online_seeds.fields_differing(cpu, cpu) == {}
  bigger = door_open_online.get_config('cpu')
  with bigger.unlocked():
    bigger.model.extra = 1
  with pytest.raises(ValueError, match=r'fields the first --configs lacks \(model.extra\)'):
    online_seeds.fields_differing(cpu, bigger, 'x')
