"""The planning benchmark's results (experiments.benchmark_planning): latency statistics, the
bound ratio against the measured peak, the ratio to MPPI, and the markdown table."""

import copy

import numpy as np

from benchmarks import write_results


def finish(entries: list, peak_gflops: float, device: dict) -> list:
  """Adds latency stats, peak, bound ratio and the ratio to MPPI's median latency."""
  for e in entries:
    lat = np.asarray(e.pop('latencies_ms')) * 1e3
    e['latency_ms'] = dict(median=float(np.median(lat)), min=float(lat.min()),
                           max=float(lat.max()), n=int(lat.size))
    e['peak_gflops'] = peak_gflops
    e['bound_ratio'] = e['latency_ms']['median'] / 1e3 / (e['gflop'] / peak_gflops)
    e['device'] = device
  mppi_ms = next((e['latency_ms']['median'] for e in entries if e['variant'] == 'mppi'), None)
  for e in entries:
    e['latency_vs_mppi'] = e['latency_ms']['median'] / mppi_ms if mppi_ms else None
  return entries


def write_partial(out: str, entries: list, peak_gflops: float, device: dict,
                  quiet: bool = True) -> list:
  """Writes the configurations measured so far (finished copies; `entries` is left as it is);
  says where only when not `quiet` (the last write)."""
  done = finish(copy.deepcopy(entries), peak_gflops, device)
  write_results(out, done, markdown(done), quiet=quiet)
  return done


def markdown(entries: list) -> str:
  dev = entries[0]['device']
  lines = [f"Device: {dev['name']} ({dev['platform']}), JAX {dev['jax']}; peak "
           f"{entries[0]['peak_gflops']:.1f} GFLOP/s (float32 matmul); 1-min load average at "
           f"start {dev['loadavg_1min_at_start']:.2f}.", '',
           '| configuration | params | K | steps | compile s | median ms | min ms | max ms '
           '| GFLOP (hand) | GFLOP (XLA) | bound ratio | / MPPI | encode ms |',
           '| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: '
           '| ---: |']
  for e in entries:
    l, vs = e['latency_ms'], e['latency_vs_mppi']
    encode = f"{e['encode_ms']:.2f}" if 'encode_ms' in e else '-'  # MPPI's: not timed apart.
    lines.append(f"| {e['name']} | {e['num_params'] / 1e6:.2f}M | {e['num_candidates']} | "
                 f"{e['steps']} | {e['compile_s']:.1f} | {l['median']:.1f} | {l['min']:.1f} | "
                 f"{l['max']:.1f} | {e['gflop']:.2f} | {e['gflop_xla']:.2f} | "
                 f"{e['bound_ratio']:.2f} | {'-' if vs is None else f'{vs:.2f}'} | {encode} |")
  return '\n'.join(lines) + '\n'
