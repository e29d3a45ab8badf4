"""Where the time of one `plan` call (or training update) goes: XLA ops grouped by network and
by kind of work.

`profile_plan(config)` (`profile_update(config)` for the update) traces jitted calls with
jax.profiler, reads the per-op events of the trace and maps each to its HLO instruction's source
location (the `op_name` metadata of the compiled module): the network (proposal, dynamics,
objective, actor, encoder, critics) and the kind of work
(matmul, attention element-wise, LayerNorm, MLP element-wise such as GELU, random numbers,
other). Op times are summed per op (loop and conditional events, which can span their bodies,
are left out), so they do not add up exactly to the wall time (loop and dispatch overheads are
in neither, and XLA:CPU runs independent ops on several threads at once); both are reported,
with the number of op events, how many are shorter than 20 us, and how long each thread was
busy running ops. The event names are XLA:CPU's (thunk runtime); on other
backends the table may come out mostly 'other'. CLI: experiments.diagnose profile.
"""

import collections
import glob
import gzip
import json
import math
import os
import re
import tempfile
import time

import jax
import numpy as np

from benchmarks.training import random_batch
from ld_mpc_jax.model.models import encode, init_params
from ld_mpc_jax.plan.planner import make_plan
from ld_mpc_jax.learn.train_state import LearnSettings, create_train_state, make_update

NETWORKS = (('ActionProposal', 'proposal'), ('LatentDynamics', 'dynamics'),
            ('TrajectoryDynamics', 'dynamics'), ('SequenceObjective', 'objective'),
            ('Actor', 'actor'), ('Encoder', 'encoder'), ('Critics', 'critics'))
SHORT_OP_US = 20
KINDS = ('matmul', 'attention element-wise', 'layernorm', 'mlp element-wise (GELU, residual)',
         'random numbers', 'other')
# Trace events that are not single XLA ops (wrappers, waits, Python frames), and control flow
# (a while loop's event can span its body's ops, which are traced themselves).
_NOT_OPS = re.compile(r'^(\$|Thunk|SlinkyThreadPool|PjitFunction|end: |ParseArguments|'
                      r'CommonPjRt|while|conditional|call)')


def classify(op_name: str, is_matmul: bool) -> tuple:
  """(network, kind) of an HLO instruction from its op_name metadata (its JAX source path)."""
  network = next((short for long, short in NETWORKS if long in op_name), 'other')
  if is_matmul:
    kind = 'matmul'
  elif re.search(r'_normal|_uniform|threefry|random_bits', op_name):
    kind = 'random numbers'
  elif re.search(r'/ln_|LayerNorm', op_name):
    kind = 'layernorm'
  elif '/attn' in op_name:
    kind = 'attention element-wise'
  elif re.search(r'/block_\d+/[^/]+$', op_name):
    kind = 'mlp element-wise (GELU, residual)'
  else:
    kind = 'other'
  return network, kind


def hlo_ops(hlo_text: str) -> dict:
  """instruction name -> (op_name metadata, is a matmul) for every instruction with metadata.

  An instruction is a matmul if it is a dot or a fusion whose computation contains one (library
  fusions such as XLA:CPU's YNNPACK ones also wrap reductions and element-wise work).
  """
  bodies = {m.group(1): m.group(2) for m in re.finditer(
      r'^%?([\w.\-]+) [^\n]*\{\n(.*?)\n\}', hlo_text, re.S | re.M)}
  ops = {}
  for line in hlo_text.splitlines():
    m = re.match(r'\s*%([\w.\-]+) = .*?op_name="([^"]+)"', line)
    if m:
      called = re.search(r'calls=%([\w.\-]+)', line)
      is_matmul = bool(re.search(r'= \S+ dot\(', line)) or bool(
          called and re.search(r' dot\(', bodies.get(called.group(1), '')))
      ops[m.group(1)] = (m.group(2), is_matmul)
  return ops


def op_events(trace_dir: str) -> list:
  """(name, thread id, start us, duration us) of every op event in the newest perfetto trace
  under trace_dir."""
  files = sorted(glob.glob(os.path.join(trace_dir, '**', '*.trace.json.gz'), recursive=True),
                 key=os.path.getmtime)
  if not files:
    raise FileNotFoundError(f'jax.profiler wrote no perfetto trace under {trace_dir}')
  with gzip.open(files[-1]) as f:
    events = json.load(f)['traceEvents']
  return [(e['name'], e.get('tid'), e['ts'], e.get('dur', 0)) for e in events
          if e.get('ph') == 'X' and not _NOT_OPS.match(e.get('name', ''))]


def op_times(trace_dir: str) -> collections.Counter:
  """Summed duration [us] per trace event name in the newest perfetto trace under trace_dir."""
  times = collections.Counter()
  for name, _, _, dur in op_events(trace_dir):
    times[name] += dur
  return times


def _busy_us(intervals) -> float:
  """Length of the union of (start, end) intervals."""
  busy, end = 0.0, -math.inf
  for a, b in sorted(intervals):
    if b > end:
      busy += b - max(a, end)
      end = b
  return busy


def _profile(compiled, call, calls: int) -> dict:
  """Traces `calls` calls of call() (after one warm-up) and groups the op times of the
  `compiled` program's instructions by network and kind (module docstring)."""
  call()
  with tempfile.TemporaryDirectory() as trace_dir:
    with jax.profiler.trace(trace_dir, create_perfetto_trace=True):
      for _ in range(calls):
        call()
    events = op_events(trace_dir)
  ops = hlo_ops(compiled.as_text())
  table = collections.defaultdict(float)
  unmatched = 0.0
  threads = collections.defaultdict(list)
  for name, tid, ts, dur in events:
    if name in ops:
      table[classify(*ops[name])] += dur / 1e3 / calls
    else:
      unmatched += dur / 1e3 / calls
    threads[tid].append((ts, ts + dur))
  busy = sorted((_busy_us(v) / 1e3 / calls for v in threads.values()), reverse=True)
  wall = []  # Plain wall time of the same calls without the profiler.
  for _ in range(calls):
    t0 = time.perf_counter()
    call()
    wall.append(time.perf_counter() - t0)
  return dict(ms_per_call={f'{n}/{k}': v for (n, k), v in sorted(table.items())},
              ops_ms=sum(table.values()), unmatched_ms=unmatched,
              wall_ms_median=float(np.median(wall)) * 1e3, calls=calls,
              op_events_per_call=len(events) / calls,
              short_op_events_per_call=sum(e[3] < SHORT_OP_US for e in events) / calls,
              thread_busy_ms=[b for b in busy if b >= 0.01])


def profile_plan(config, calls: int = 3) -> dict:
  """Traces `calls` calls of make_plan(config) (random parameters, after one warm-up call).

  Returns {'ms_per_call': {'network/kind': ms}, 'ops_ms', 'unmatched_ms', 'wall_ms_median',
  'calls', 'op_events_per_call', 'short_op_events_per_call', 'thread_busy_ms'}.
  """
  params = init_params(config, jax.random.key(0))
  z = encode(params, np.linspace(-1.0, 1.0, config.obs_dim, dtype=np.float32))
  key = jax.random.key(1)
  compiled = make_plan(config).lower(params, z, key).compile()
  return _profile(compiled, lambda: jax.block_until_ready(compiled(params, z, key)), calls)


def profile_update(config, calls: int = 3) -> dict:
  """As profile_plan, for one training update of `config` on a synthetic batch."""
  learn = LearnSettings.from_config(config)
  state = create_train_state(learn, jax.random.key(0))
  batch = random_batch(config, config.train.batch_size)
  key = jax.random.key(1)
  compiled = make_update(learn).lower(state, batch, key).compile()

  def call():  # The update donates its state: carry the new one.
    nonlocal state
    state, metrics = compiled(state, batch, key)
    jax.block_until_ready((state, metrics))

  return _profile(compiled, call, calls)


def markdown(result: dict) -> str:
  networks = sorted({k.split('/')[0] for k in result['ms_per_call']})
  head = '| kind | ' + ' | '.join(networks) + ' | total | share |'
  lines = [head, '| --- |' + ' ---: |' * (len(networks) + 2)]
  total = result['ops_ms']
  for kind in KINDS:
    row = [result['ms_per_call'].get(f'{n}/{kind}', 0.0) for n in networks]
    if sum(row):
      cells = ' | '.join(f'{v:.1f}' for v in row)
      lines.append(f'| {kind} | {cells} | {sum(row):.1f} | {sum(row) / total:.0%} |')
  lines.append(f'\nms per call. Ops summed: {total:.1f} ms (+ {result["unmatched_ms"]:.1f} ms in '
               f'events without a source location); wall time of a call without the profiler: '
               f'{result["wall_ms_median"]:.1f} ms (median of {result["calls"]}).')
  if 'op_events_per_call' in result:
    busy = ', '.join(f'{b:.1f}' for b in result['thread_busy_ms'])
    lines.append(f'Op events per call: {result["op_events_per_call"]:.0f}, '
                 f'{result["short_op_events_per_call"]:.0f} of them shorter than {SHORT_OP_US} us; '
                 f'ms per call each thread was busy running ops: {busy}.')
  return '\n'.join(lines)
