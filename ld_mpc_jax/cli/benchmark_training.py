r"""Training benchmark: time and FLOPs of one update step, and the bound ratio against the peak.

  python -m experiments.benchmark_training                       # :cpu preset and reference
  python -m experiments.benchmark_training --configs=door_open.py:cpu --repeats=20
  python -m experiments.benchmark_training --configs=door_open.py:smoke --repeats=2 --out=b.json
  python -m experiments.benchmark_training --data_parallel       # batch split over all devices
  python -m experiments.benchmark_training --online_seeds=1,3,5 --online_seed_devices=0 \
      --configs=door_open_online.py:cpu --online_env_steps=4000  # seeds in one online run
  python -m experiments.benchmark_training --online_seeds=1,3 --online_seed_devices=1,2 \
      --configs=door_open_online.py:cpu    # and spread over 2 devices (train.seed_devices)

Each --configs entry is a config file with an optional :preset, as for experiments.train.
Parameters are random and batches synthetic. Writes a JSON list, one entry per config (name,
step_ms {median, min, max, n} after compilation and warm-up, gflop per step from XLA's cost
analysis with the scans unrolled, peak_gflops measured in this run, bound_ratio = measured time /
FLOP-bound time, devices), and a markdown table next to it (.md). Method: docs/scaling.md.
With --online_seeds, instead: online training of the first config with N training seeds in one
run for each N, one after the other in this process (benchmarks/online_seeds.py).
With --online_breakdown=1,3 instead: where a simulator step's time goes in online training of the
first config (environments, plan, update, buffer sampling, host), for each N seeds in one run,
--repeats runs each, and the FLOPs of a decision and an update against the peak
(benchmarks/online_breakdown.py; docs/scaling.md):

  python -m experiments.benchmark_training --configs=door_open_online.py:cpu \
      --online_breakdown=1,3 --repeats=3 --out=runs/bench/online_breakdown.json
"""

import importlib.util
import os

from absl import flags, logging

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import CONFIG_DIR

_CONFIGS = flags.DEFINE_list('configs', ['door_open.py:cpu', 'door_open.py'],
                             'Config files with optional :preset (the reference has none).')
_REPEATS = flags.DEFINE_integer('repeats', 10, 'Timed update steps per config (after warm-up).')
_WARMUP = flags.DEFINE_integer('warmup', 2, 'Untimed steps after compilation.')
_DATA_PARALLEL = flags.DEFINE_bool('data_parallel', False, 'Split the batch over all devices.')
_OUT = flags.DEFINE_string('out', 'runs/benchmark/benchmark_training.json',
                           'JSON output; .md written beside.')
_PEAK_SIZE = flags.DEFINE_integer('peak_size', 2048, 'Square float32 matmul for the peak.')
_PEAK_REPEATS = flags.DEFINE_integer('peak_repeats', 10, 'Timed matmuls for the peak.')
_ONLINE_SEEDS = flags.DEFINE_list('online_seeds', [], 'Numbers of training seeds in one online '
                                  'run to time, e.g. 1,3,5 (the first config must be online).')
_ONLINE_OVERLAP = flags.DEFINE_enum('online_overlap', 'on', ['on', 'off', 'both'],
                                    'Online updates dispatched ahead of the environment steps '
                                    "that call for them ('on', as runs train), after ('off'), or "
                                    "both, one after the other (the gain, in the same process).")
_ONLINE_DEVICES = flags.DEFINE_list('online_seed_devices', ['1'], 'With --online_seeds: each '
                                     'N also with its seeds spread over each of these numbers '
                                     'of devices (train.seed_devices; on a CPU, virtual '
                                     'devices made before JAX starts); 0: one per seed.')
_BREAKDOWN = flags.DEFINE_list('online_breakdown', [], 'Numbers of training seeds in one online '
                                'run whose time per simulator step to break down, e.g. 1,3.')
_WAVES = flags.DEFINE_integer('online_waves', 3, 'With --online_breakdown: timed waves per run '
                              '(after the seed waves and the compiling wave).')
_ONLINE_STEPS = flags.DEFINE_integer('online_env_steps', 4000, 'Environment steps (simulator '
                                     'steps) of each timed online run, seed waves included.')


def load_config(spec: str):
  """'door_open.py:cpu' (or a path) -> get_config('cpu') of that file."""
  path, _, preset = spec.partition(':')
  if not os.path.exists(path):
    path = os.path.join(CONFIG_DIR, path)
  module_spec = importlib.util.spec_from_file_location('_benchmark_config', path)
  module = importlib.util.module_from_spec(module_spec)
  module_spec.loader.exec_module(module)
  return module.get_config(preset or None)


OVERRIDES = []  # 'field=value' items of --config.field=value, for every config.


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)  # Keep orbax's per-save INFO lines out of the output.
  if _REPEATS.value < 1 or _WAVES.value < 1:
    cli.fail('--repeats and --online_waves must be at least 1')
  devices = max(int(d) for d in _ONLINE_DEVICES.value)
  if _BREAKDOWN.value:  # One device per seed, as runs train by default.
    devices = max(devices, *(int(n) for n in _BREAKDOWN.value))
  if _ONLINE_SEEDS.value and 0 in [int(d) for d in _ONLINE_DEVICES.value]:  # One per seed.
    devices = max(devices, *(int(n) for n in _ONLINE_SEEDS.value))
  if (_ONLINE_SEEDS.value or _BREAKDOWN.value) and devices > 1:  # Before JAX starts: the CPU as that many devices.
    import jax
    jax.config.update('jax_num_cpu_devices', devices)
  from ld_mpc_jax.configs.overrides import parse_items, with_overrides
  import benchmarks as bench
  from benchmarks import hardware, training
  from ld_mpc_jax.model.config_checks import validate_config
  configs = {}
  with cli.one_line_errors():
    for spec in _CONFIGS.value:
      configs[spec] = with_overrides(load_config(spec), parse_items(OVERRIDES))
      validate_config(configs[spec])
  device = hardware.device_info()
  print(f"device: {device['name']} x {device['device_count']}; load average "
        f"{device['loadavg_1min_at_start']:.2f}")
  if _BREAKDOWN.value:
    from benchmarks import online_breakdown
    spec = _CONFIGS.value[0]
    peak = hardware.measure_peak(_PEAK_SIZE.value, _PEAK_REPEATS.value)
    entries = online_breakdown.run(configs[spec], [int(n) for n in _BREAKDOWN.value],
                                   _WAVES.value, peak, _REPEATS.value)
    table = online_breakdown.markdown(entries, spec, device['name'])
    print(table)
    bench.write_results(_OUT.value, [dict(e, device=device) for e in entries], table)
    return
  if _ONLINE_SEEDS.value:
    from benchmarks import online_seeds
    spec = _CONFIGS.value[0]
    overlaps = {'on': (True,), 'off': (False,), 'both': (True, False)}[_ONLINE_OVERLAP.value]
    entries = online_seeds.benchmark_seeds(configs[spec], [int(n) for n in _ONLINE_SEEDS.value],
                                           _ONLINE_STEPS.value, overlaps=overlaps,
                                           seed_devices=[int(d) for d in _ONLINE_DEVICES.value])
    table = online_seeds.markdown(entries, spec, _ONLINE_STEPS.value, device['name'])
    print(table)
    bench.write_results(_OUT.value, [dict(e, device=device) for e in entries], table)
    return
  peak = hardware.measure_peak(_PEAK_SIZE.value, _PEAK_REPEATS.value)
  print(f'peak: {peak:.1f} GFLOP/s ({_PEAK_SIZE.value}^2 float32 matmul)', flush=True)
  entries = []
  for spec, config in configs.items():
    entry = training.benchmark_update(spec, config, _REPEATS.value, _WARMUP.value,
                                      data_parallel=_DATA_PARALLEL.value)
    entries.append(entry)
    print(f"{spec}: compile {entry['compile_s']:.1f} s, {entry['gflop']:.2f} GFLOP/step "
          f"(cost analysis with scan bodies once: {entry['gflop_xla_once']:.2f})", flush=True)
  peak = max(peak, hardware.measure_peak(_PEAK_SIZE.value, _PEAK_REPEATS.value))
  entries = [training.finish(e, peak, device) for e in entries]
  table = training.markdown(entries)
  print(table)
  bench.write_results(_OUT.value, entries, table)
