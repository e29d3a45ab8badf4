"""The machine a benchmark runs on: its description and its measured float32 matmul peak."""

import os
import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.flops import matmul_flops


def device_info() -> dict:
  """The machine: CPU model and core count, or the accelerator's device kind."""
  dev = jax.devices()[0]
  info = {'platform': dev.platform, 'device_kind': dev.device_kind,
          'cpu_count': os.cpu_count(), 'jax': jax.__version__,
          'device_count': jax.device_count(), 'loadavg_1min_at_start': os.getloadavg()[0]}
  try:
    with open('/proc/cpuinfo') as f:
      info['cpu_model'] = next(l.split(':', 1)[1].strip() for l in f if l.startswith('model name'))
  except (OSError, StopIteration):
    info['cpu_model'] = 'unknown'
  info['name'] = (f"{info['cpu_model']}, {info['cpu_count']} cores" if dev.platform == 'cpu'
                  else f'{dev.device_kind} ({dev.platform})')
  return info


def measure_peak(n: int, repeats: int) -> float:
  """Median GFLOP/s of an [n, n] x [n, n] float32 matmul on the default device."""
  ka, kb = jax.random.split(jax.random.key(0))
  a, b = jax.random.normal(ka, (n, n)), jax.random.normal(kb, (n, n))
  matmul = jax.jit(jnp.matmul)
  matmul(a, b).block_until_ready()
  times = []
  for _ in range(repeats):
    t0 = time.perf_counter()
    matmul(a, b).block_until_ready()
    times.append(time.perf_counter() - t0)
  return matmul_flops(n) / float(np.median(times)) / 1e9
