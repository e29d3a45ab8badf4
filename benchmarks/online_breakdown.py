"""Where a simulator step's time goes in online training (ld_mpc_jax.runs.online), for N seeds in
one run: the environments (MuJoCo and the Meta-World wrapper: resets and steps), the acting
`plan` call, the update, buffer sampling, and everything else on the host (Python, transfers,
logging, the buffer's bookkeeping), each in ms per simulator step and as a share.

Method: an online job from scratch with evaluation and checkpoints off runs its seed waves and
its first planner wave (which compiles the planner and the update, and makes the seed steps'
share of updates at once) untimed, then `waves` timed waves. Each part is timed around its own
calls, and the update waits for its result (`jax.block_until_ready`) before its time is read, so
the parts are exclusive and add up with "host, other" to the timed waves' wall time. Runs
dispatch the updates ahead of the environment steps (they overlap with MuJoCo); that overlap is
removed here to attribute the time, so the wall time per step here is an upper bound of a real
run's. The untimed rate of the same waves is `benchmark_training --online_seeds`.

FLOPs: one acting decision (the acting config's `plan` for one environment, scans corrected as
`benchmark_planning` does) and one update (scans unrolled, `benchmarks.training`), each set
against the float32 matmul peak measured in the same run: bound ratio = measured time / the
time the FLOPs take at the peak. A decision's time is the plan call's time per environment-
decision (the call plans for every active environment of every seed at once).
"""

import contextlib
import statistics
import tempfile
import time
from typing import Dict, List, Sequence

import jax
import ml_collections

PARTS = ('environments', 'plan', 'update', 'buffer sampling', 'host, other')


@contextlib.contextmanager
def _timed(totals: Dict[str, float], counts: Dict[str, int]):
  """Wraps the online loop's methods so that each part's seconds add into `totals`."""
  from ld_mpc_jax.data.online_buffer import Buffer  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.online import learner as online_learner, seats as online_seats  # pylint: disable=g-import-not-at-top

  def block_states(learner, _):
    jax.block_until_ready(learner.states)

  def count_decisions(_, out):
    counts['decisions'] += sum(int(a.shape[0]) for a in out[0] if a is not None)

  wrapped = [(online_seats.SeatWave, 'step', 'environments', None),
             (online_seats.SeatWave, '__init__', 'environments', None),  # The resets.
             (online_seats.WavePolicy, '__call__', 'plan', count_decisions),
             (online_learner.Learner, '_updates', 'update', block_states),
             (Buffer, 'sample', 'buffer sampling', None)]
  originals = [(cls, name, getattr(cls, name)) for cls, name, _, _ in wrapped]

  def timer(fn, part, after):
    def timed(self, *args, **kwargs):
      start = time.perf_counter()
      out = fn(self, *args, **kwargs)
      if after is not None:
        after(self, out)
      totals[part] += time.perf_counter() - start
      return out
    return timed

  try:
    for (cls, name, part, after), (_, _, fn) in zip(wrapped, originals):
      setattr(cls, name, timer(fn, part, after))
    yield
  finally:
    for cls, name, fn in originals:
      setattr(cls, name, fn)


def _flops(config: ml_collections.ConfigDict) -> Dict[str, float]:
  """GFLOP of one acting decision (one environment) and of one update."""
  from benchmarks import flops, training  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.model.settings import ModelSettings, PlanSettings  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.online.settings import OnlineSettings  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.plan import planner  # pylint: disable=g-import-not-at-top
  model = ModelSettings.from_config(config)
  act = OnlineSettings.from_config(config).acting_plan(PlanSettings.from_config(config))
  decision = flops.xla_plan_flops(model, act, planner.build_plan(model, act))['total']
  update = training.benchmark_update('update', config, repeats=1, warmup=0)  # One seed's.
  return dict(decision_gflop=decision / 1e9, update_gflop=update['gflop'])


def breakdown(config: ml_collections.ConfigDict, num_seeds: int, waves: int) -> dict:
  """One entry: ms per simulator step of each part over `waves` timed waves of `num_seeds`
  seeds, the simulator steps, decisions and updates they made, and the timed wall seconds."""
  from ld_mpc_jax.runs import online  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.configs.overrides import with_overrides  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.runs.seed_plan import seed_plans  # pylint: disable=g-import-not-at-top
  o = config.online
  wave_steps = o.num_envs * o.episode_steps
  untimed = o.seed_steps + wave_steps  # Seed waves, then the wave that compiles.
  total = untimed + waves * wave_steps
  c = with_overrides(config, {'train.num_seeds': num_seeds, 'eval.episodes': 0,
                              'online.env_steps': total, 'online.eval_every': total,
                              'online.checkpoint_every': total})
  totals = {p: 0.0 for p in PARTS}
  counts = {'decisions': 0}
  with tempfile.TemporaryDirectory() as workdir:
    job = online.online_job(seed_plans(c, workdir), None)
    job.bar.disable = True
    with _timed(totals, counts):
      while job.progress < untimed:
        before = job.progress
        job.advance()
        job.log(before)
      for part in totals:
        totals[part] = 0.0
      counts['decisions'] = 0
      steps0, updates0, start = job.progress, job.counters['updates'], time.perf_counter()
      while job.progress < total:
        before = job.progress
        job.advance()
        job.log(before)
      wall = time.perf_counter() - start
    job.bar.close()
  steps = (job.progress - steps0) * num_seeds  # Every seed's simulator steps.
  totals['update'] -= totals['buffer sampling']  # Sampled inside `_updates`: counted once.
  totals['host, other'] = wall - sum(v for k, v in totals.items() if k != 'host, other')
  return dict(num_seeds=num_seeds, waves=waves, sim_steps=steps, wall_s=wall,
              decisions=counts['decisions'],
              updates=(job.counters['updates'] - updates0) * num_seeds,
              ms_per_sim_step={k: v / steps * 1e3 for k, v in totals.items()},
              share={k: v / wall for k, v in totals.items()},
              sim_steps_per_s=steps / wall,
              plan_ms_per_decision=totals['plan'] / max(counts['decisions'], 1) * 1e3,
              update_ms_per_update=totals['update'] / max(
                  (job.counters['updates'] - updates0) * num_seeds, 1) * 1e3)


def run(config: ml_collections.ConfigDict, seeds: Sequence[int], waves: int,
        peak_gflops: float, repeats: int = 1) -> List[dict]:
  """`breakdown` for each N in `seeds`, `repeats` times each (alternating), medians per part;
  with the FLOPs of a decision and an update against `peak_gflops`."""
  runs = {n: [] for n in seeds}
  for r in range(repeats):
    for n in seeds:
      print(f'online breakdown: {n} seed(s), repeat {r + 1} of {repeats} ...', flush=True)
      runs[n].append(breakdown(config, n, waves))
  fl = _flops(config)
  out = []
  for n, entries in runs.items():
    med = lambda f: statistics.median(f(e) for e in entries)
    e = dict(entries[0], repeats=len(entries),
             ms_per_sim_step={p: med(lambda x: x['ms_per_sim_step'][p]) for p in PARTS},
             sim_steps_per_s=med(lambda x: x['sim_steps_per_s']),
             plan_ms_per_decision=med(lambda x: x['plan_ms_per_decision']),
             update_ms_per_update=med(lambda x: x['update_ms_per_update']), **fl,
             peak_gflops=peak_gflops)
    total = sum(e['ms_per_sim_step'].values())
    e['share'] = {p: v / total for p, v in e['ms_per_sim_step'].items()}
    e['decision_bound_ratio'] = e['plan_ms_per_decision'] / (fl['decision_gflop'] / peak_gflops
                                                             * 1e3)
    e['update_bound_ratio'] = e['update_ms_per_update'] / (fl['update_gflop'] / peak_gflops
                                                           * 1e3)
    out.append(e)
  return out


def markdown(entries: List[dict], spec: str, device: str) -> str:
  """The breakdown table (one column per number of seeds) and the FLOP table."""
  e0 = entries[0]
  lines = [f'Online training, {spec}, on {device}: ms per simulator step (all seeds\' steps '
           f'counted), over {e0["waves"]} timed waves after the seed waves and the compiling '
           f'wave, median of {e0["repeats"]} run(s); updates wait for their result here '
           '(no overlap with MuJoCo).', '',
           '| part | ' + ' | '.join(f'{e["num_seeds"]} seed(s): ms | share' for e in entries)
           + ' |', '| --- |' + ' ---: | ---: |' * len(entries)]
  for p in PARTS:
    lines.append(f'| {p} | ' + ' | '.join(
        f'{e["ms_per_sim_step"][p]:.2f} | {e["share"][p]:.0%}' for e in entries) + ' |')
  lines.append('| **total** | ' + ' | '.join(
      f'**{sum(e["ms_per_sim_step"].values()):.2f}** | 100%' for e in entries) + ' |')
  lines.append('| simulator steps/s, all seeds | ' + ' | '.join(
      f'{e["sim_steps_per_s"]:.1f} | ' for e in entries) + ' |')
  lines += ['', f'FLOPs against the float32 matmul peak measured in this run '
            f'({e0["peak_gflops"]:.1f} GFLOP/s); bound ratio = measured time / FLOP-bound time.',
            '', '| seeds | decision GFLOP | ms per decision | bound ratio | update GFLOP | '
            'ms per update | bound ratio |', '| ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
  for e in entries:
    lines.append(f'| {e["num_seeds"]} | {e["decision_gflop"]:.4f} | '
                 f'{e["plan_ms_per_decision"]:.2f} | {e["decision_bound_ratio"]:.1f} | '
                 f'{e["update_gflop"]:.3f} | {e["update_ms_per_update"]:.2f} | '
                 f'{e["update_bound_ratio"]:.1f} |')
  return '\n'.join(lines) + '\n'
