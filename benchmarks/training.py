"""Training throughput: time and FLOPs of one update step, and its bound ratio against the peak.

FLOPs come from XLA's cost analysis. That analysis counts the body of a `lax.scan` once, not once
per iteration, and the update has scans: the latent rollout of the objective's training
(H transitions, each a denoising loop) and its backward pass, and the n-step value targets.
`unrolled_flops` corrects for them generally: it traces the function to a jaxpr, re-traces that
jaxpr with every scan replaced by its iterations written out one after another (scans inside
scans too), and reads the cost analysis of that scan-free program: the FLOPs of every iteration.
(benchmarks.flops corrects the planner instead by lowering each loop body on its own.)
"""

import dataclasses
import time
from typing import Callable, Dict, Optional

import jax
from jax.extend import core as jax_core
import jax.numpy as jnp
import ml_collections
import numpy as np

from ld_mpc_jax.ops import sharding
from ld_mpc_jax.model import tasks
from benchmarks.flops import compiled_flops
from ld_mpc_jax.model.models import count_params
from ld_mpc_jax.learn.train_state import LearnSettings, create_train_state, make_update

# Primitives whose sub-jaxpr is evaluated in line, so that the scans inside them are unrolled too.
_INLINE = {'pjit': 'jaxpr', 'jit': 'jaxpr', 'closed_call': 'call_jaxpr',
           'core_call': 'call_jaxpr', 'remat': 'jaxpr', 'checkpoint': 'jaxpr',
           'custom_jvp_call': 'call_jaxpr', 'custom_vjp_call': 'call_jaxpr',
           'custom_vjp_call_jaxpr': 'fun_jaxpr'}


def _eval_unrolled(jaxpr, consts, *args):
  """Evaluates an (open) jaxpr like jax.core.eval_jaxpr, writing every scan out iteration by
  iteration."""
  env = {}
  read = lambda v: v.val if isinstance(v, jax_core.Literal) else env[v]
  for var, val in zip(jaxpr.constvars, consts):
    env[var] = val
  for var, val in zip(jaxpr.invars, args):
    env[var] = val
  for eqn in jaxpr.eqns:
    invals = [read(v) for v in eqn.invars]
    name = eqn.primitive.name
    if name == 'scan':
      outs = _unroll_scan(eqn, invals)
    elif name in _INLINE and _INLINE[name] in eqn.params:
      sub = eqn.params[_INLINE[name]]
      closed = sub if isinstance(sub, jax_core.ClosedJaxpr) else jax_core.ClosedJaxpr(sub, ())
      outs = _eval_unrolled(closed.jaxpr, closed.consts, *invals)
    else:
      params = eqn.primitive.get_bind_params(eqn.params)
      subfuns, params = params if isinstance(params, tuple) else ((), params)  # Older JAX: pair.
      outs = eqn.primitive.bind(*subfuns, *invals, **params)
      outs = outs if eqn.primitive.multiple_results else [outs]
    for var, val in zip(eqn.outvars, outs):
      env[var] = val
  return [read(v) for v in jaxpr.outvars]


def _scan_layout(eqn, body) -> tuple:
  """(number of consts, number of carry leaves) among a scan's operands (consts, carry, xs)."""
  if 'num_consts' in eqn.params:  # JAX <= 0.10 says so.
    return eqn.params['num_consts'], eqn.params['num_carry']
  # JAX 0.11 no longer does: read it off the shapes. A carry output has its body output's shape,
  # a stacked ys output one more leading axis; an xs operand has one more leading axis than its
  # body input, a const or carry operand the same shape.
  shape = lambda v: tuple(v.aval.shape)
  n_carry = sum(shape(o) == shape(b) for o, b in zip(eqn.outvars, body.outvars))
  n_xs = sum(shape(o) != shape(b) for o, b in zip(eqn.invars, body.invars))
  return len(eqn.invars) - n_xs - n_carry, n_carry


def _unroll_scan(eqn, invals):
  """scan(consts, carry, xs) as `length` applications of its body: (carry..., ys...)."""
  params, body = eqn.params, eqn.params['jaxpr']
  length = params['length']
  body_jaxpr, body_consts = getattr(body, 'jaxpr', body), getattr(body, 'consts', ())
  n_consts, n_carry = _scan_layout(eqn, body_jaxpr)
  consts, carry = invals[:n_consts], invals[n_consts:n_consts + n_carry]
  xs = invals[n_consts + n_carry:]
  ys = []
  steps = range(length - 1, -1, -1) if params['reverse'] else range(length)
  for i in steps:
    outs = _eval_unrolled(body_jaxpr, body_consts, *consts, *carry, *[x[i] for x in xs])
    carry, y = outs[:n_carry], outs[n_carry:]
    ys.append(y)
  if params['reverse']:
    ys.reverse()
  n_ys = len(body_jaxpr.outvars) - n_carry
  stacked = [jnp.stack([y[j] for y in ys]) for j in range(n_ys)]
  return list(carry) + stacked


def unrolled_flops(fn: Callable, *args, once: Optional[float] = None) -> Dict[str, float]:
  """XLA FLOPs of fn(*args) as compiled, and with every scan iteration counted.

  args may be arrays or jax.ShapeDtypeStruct; nothing is executed. `once`: the cost analysis of
  jit(fn) if the caller already compiled it.

  Returns:
    {'xla_once': cost analysis of jit(fn) (scan bodies counted once),
     'total': cost analysis of the same computation with the scans unrolled}.
  """
  closed = jax.make_jaxpr(fn)(*args)
  flat = jax.tree_util.tree_leaves(args)
  if once is None:
    once = compiled_flops(jax.jit(fn).lower(*args).compile())
  unrolled = jax.jit(lambda *xs: _eval_unrolled(closed.jaxpr, closed.consts, *xs))
  return {'xla_once': once, 'total': compiled_flops(unrolled.lower(*flat).compile())}


def random_batch(config: ml_collections.ConfigDict, batch_size: int, seed: int = 0) -> dict:
  """A training batch of the config's shapes: obs [B, H+2, D], action [B, H+1, A], reward
  [B, H+1], and for a multi-task config task [B] (equal task-major shares)."""
  rng = np.random.default_rng(seed)
  h, b = config.horizon, batch_size
  batch = dict(obs=rng.normal(size=(b, h + 2, config.obs_dim)).astype(np.float32),
               action=rng.uniform(-1, 1, (b, h + 1, config.action_dim)).astype(np.float32),
               reward=rng.uniform(0, 10, (b, h + 1)).astype(np.float32))
  trained = tasks.Tasks.from_config(config)
  if trained.multitask:
    n = len(trained)
    batch['task'] = np.repeat(np.arange(n, dtype=np.int32), b // n)
  return batch


def benchmark_update(name: str, config: ml_collections.ConfigDict, repeats: int,
                     warmup: int = 2, data_parallel: bool = False,
                     count_flops: bool = True) -> dict:
  """Times `repeats` update steps of `config` after compilation and `warmup` untimed steps.

  Parameters are random and batches synthetic (time does not depend on their values); every
  step gets a new batch and key, as in training. With `data_parallel` (or
  config.train.data_parallel) the update runs on a mesh over all devices
  (config.train.batch_size is the global batch).

  Returns:
    An entry without the peak: name, step_s [repeats] (seconds), compile_s, gflop (per step,
    scans unrolled), gflop_xla_once (scan bodies counted once), num_params, batch_size, devices.
  """
  b = config.train.batch_size
  learn = LearnSettings.from_config(config)
  single = dataclasses.replace(learn, data_parallel=False)  # The plain single-device update.
  data_parallel = data_parallel or config.train.data_parallel
  mesh = sharding.make_mesh() if data_parallel else None
  update = make_update(single, mesh)
  state = create_train_state(learn, jax.random.key(0))
  batches = [random_batch(config, b, seed=i) for i in range(min(4, warmup + repeats))]
  put = (lambda x: sharding.shard_batch(x, mesh)) if mesh is not None else (lambda x: x)
  if mesh is not None:
    state = sharding.replicate(state, mesh)
  num_params = count_params(state.params)
  t0 = time.perf_counter()
  compiled = update.lower(state, put(batches[0]), jax.random.key(0)).compile()
  compile_s = time.perf_counter() - t0
  times = []
  for i in range(warmup + repeats):
    batch = put(batches[i % len(batches)])
    t0 = time.perf_counter()
    state, metrics = compiled(state, batch, jax.random.key(i))
    jax.block_until_ready((state, metrics))
    if i >= warmup:
      times.append(time.perf_counter() - t0)
  if not np.isfinite(float(metrics['loss'])):
    raise FloatingPointError(f'{name}: non-finite loss in the benchmark')
  flops = {'xla_once': float('nan'), 'total': float('nan')}
  if count_flops:  # Of the single-device program: the global FLOPs of a step.
    abstract = jax.eval_shape(lambda: create_train_state(learn, jax.random.key(0)))
    once = compiled_flops(compiled) if mesh is None else None
    flops = unrolled_flops(make_update(single), abstract, batches[0], jax.random.key(0),
                           once=once)
  return dict(name=name, step_s=times, compile_s=compile_s, gflop=flops['total'] / 1e9,
              gflop_xla_once=flops['xla_once'] / 1e9, num_params=num_params, batch_size=b,
              devices=mesh.size if mesh is not None else 1)


def finish(entry: dict, peak_gflops: float, device: Optional[dict] = None) -> dict:
  """Adds step_ms {median, min, max, n}, peak_gflops and bound_ratio (time / FLOP-bound time).

  The FLOP-bound time is gflop / (peak_gflops x devices): the peak is one device's.
  """
  ms = np.asarray(entry.pop('step_s')) * 1e3
  entry['step_ms'] = dict(median=float(np.median(ms)), min=float(ms.min()),
                          max=float(ms.max()), n=int(ms.size))
  entry['peak_gflops'] = peak_gflops
  bound_ms = entry['gflop'] / (peak_gflops * entry['devices']) * 1e3
  entry['bound_ratio'] = entry['step_ms']['median'] / bound_ms
  entry['achieved_gflops'] = entry['gflop'] / entry['step_ms']['median'] * 1e3
  if device is not None:
    entry['device'] = device
  return entry


def markdown(entries: list) -> str:
  """A table of the entries (after `finish`)."""
  dev = entries[0].get('device', {})
  lines = [f"Device: {dev.get('name', '?')} ({dev.get('platform', '?')}), JAX "
           f"{dev.get('jax', '?')}; peak {entries[0]['peak_gflops']:.1f} GFLOP/s (float32 matmul, "
           f"one device); 1-min load average at start {dev.get('loadavg_1min_at_start', 0):.2f}.",
           '', '| config | params | batch | devices | compile s | median ms | min ms | max ms '
           '| GFLOP/step | GFLOP/s | bound ratio |',
           '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
  for e in entries:
    s = e['step_ms']
    lines.append(f"| {e['name']} | {e['num_params'] / 1e6:.2f}M | {e['batch_size']} | "
                 f"{e['devices']} | {e['compile_s']:.1f} | {s['median']:.1f} | {s['min']:.1f} | "
                 f"{s['max']:.1f} | {e['gflop']:.2f} | {e['achieved_gflops']:.1f} | "
                 f"{e['bound_ratio']:.2f} |")
  return '\n'.join(lines) + '\n'
