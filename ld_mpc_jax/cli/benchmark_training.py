r"""Training benchmark: time and FLOPs of one update step, and the bound ratio against the peak.

  python -m experiments.benchmark_training                       # :cpu preset and reference
  python -m experiments.benchmark_training --configs=door_open.py:cpu --repeats=20
  python -m experiments.benchmark_training --configs=door_open.py:smoke --repeats=2 --out=b.json
  python -m experiments.benchmark_training --data_parallel       # batch split over all devices
  python -m experiments.benchmark_training --online_seeds=1,3,5 --online_seed_devices=0 \
      --configs=door_open_online.py:cpu --online_env_steps=4000  # seeds in one online run
  python -m experiments.benchmark_training --online_seeds=1,3 --online_seed_devices=1,2 \
      --configs=door_open_online.py:cpu    # and spread over 2 devices (train.seed_devices)
  python -m experiments.benchmark_training --online_seeds=3 --configs=door_open_online.py:cpu \
      --online_variant=half:online.update_ratio=0.25   # and a variant, in the same process

Each --configs entry is a config file with an optional :preset, as for experiments.train.
Parameters are random and batches synthetic. Writes a JSON list, one entry per config (name,
step_ms {median, min, max, n} after compilation and warm-up, gflop per step from XLA's cost
analysis with the scans unrolled, peak_gflops measured in this run, bound_ratio = measured time /
FLOP-bound time, devices), and a markdown table next to it (.md). Method: docs/scaling.md.
With --online_seeds, instead: online training of the first config with N training seeds in one
run for each N, one after the other in this process (benchmarks/online_seeds.py); each further
config (a preset of the same file, e.g. door_open_online.py:tdmpc2_cpu) runs after it as a
variant, with its rate against the first.
With --online_breakdown=1,3 instead: where a simulator step's time goes in online training of the
first config (environments, plan, update, buffer sampling, host), for each N seeds in one run,
--repeats runs each, and the FLOPs of a decision and an update against the peak
(benchmarks/online_breakdown.py; docs/scaling.md):

  python -m experiments.benchmark_training --configs=door_open_online.py:cpu \
      --online_breakdown=1,3 --repeats=3 --out=runs/bench/online_breakdown.json

With --update_split instead: XLA's FLOPs of one update of the first config, and with each part
left out in turn (the latent rollout, the dynamics' and the proposal's losses, value members,
half the batch; counts only, nothing is timed; benchmarks/update_split.py).
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
_VARIANT = flags.DEFINE_multi_string('online_variant', [], 'With --online_seeds: NAME:field=value,'
                                      '... also run with these fields set, after the config '
                                      'as given, in this process (repeatable).')
_BREAKDOWN = flags.DEFINE_list('online_breakdown', [], 'Numbers of training seeds in one online '
                                'run whose time per simulator step to break down, e.g. 1,3.')
_WAVES = flags.DEFINE_integer('online_waves', 3, 'With --online_breakdown: timed waves per run '
                              '(after the seed waves and the compiling wave).')
_SPLIT = flags.DEFINE_bool('update_split', False, "FLOPs of the first config's update with each "
                           'part left out in turn (counts, no timing).')
_ONLINE_STEPS = flags.DEFINE_integer('online_env_steps', 4000, 'Environment steps (simulator '
                                     'steps) of each timed online run, seed waves included.')


def _check_flags():
  """(online seed counts, breakdown seed counts, most devices asked for), or ValueError naming the
  flag: before JAX starts and before anything is timed."""
  if _REPEATS.value < 1 or _WAVES.value < 1:
    raise ValueError('--repeats and --online_waves must be at least 1')
  if _ONLINE_STEPS.value < 1:
    raise ValueError(f'--online_env_steps must be at least 1, got {_ONLINE_STEPS.value}')
  seeds = cli.int_list('--online_seeds', _ONLINE_SEEDS.value, least=1)
  breakdown = cli.int_list('--online_breakdown', _BREAKDOWN.value, least=1)
  devices = cli.int_list('--online_seed_devices', _ONLINE_DEVICES.value, least=0)
  if _VARIANT.value and not seeds:
    raise ValueError('--online_variant needs --online_seeds')
  cli.check_new_output(_OUT.value, overwrite=True)  # A benchmark replaces its last result.
  return seeds, breakdown, max(devices or [1])


def _load_configs(online: bool) -> dict:
  """{spec: config} of --configs with the --config.field=value overrides, each validated; the
  first one online when `online`. ValueError naming the flag."""
  from ld_mpc_jax.configs.overrides import parse_items, with_overrides
  from ld_mpc_jax.configs import online_enabled
  from ld_mpc_jax.runs.checks import validate_config
  configs = {}
  for spec in _CONFIGS.value:
    try:
      configs[spec] = with_overrides(load_config(spec), parse_items(OVERRIDES))
    except OSError as err:
      raise ValueError(cli.config_file_error('--configs', spec, err)) from None
    validate_config(configs[spec])
  if online and not online_enabled(configs[_CONFIGS.value[0]]):
    raise ValueError(f'--online_seeds and --online_breakdown time online training: the first '
                     f'--configs ({_CONFIGS.value[0]}) is offline; e.g. '
                     '--configs=door_open_online.py:cpu')
  return configs


def load_config(spec: str):
  """'door_open.py:cpu' (or a path) -> get_config('cpu') of that file."""
  path, _, preset = spec.partition(':')
  if not os.path.exists(path):
    path = os.path.join(CONFIG_DIR, path)
  module_spec = importlib.util.spec_from_file_location('_benchmark_config', path)
  module = importlib.util.module_from_spec(module_spec)
  module_spec.loader.exec_module(module)
  return module.get_config(preset or None)


def _online_seeds(configs: dict, seeds: list, device: dict) -> None:
  """--online_seeds: online training of the first config (and its variants: --online_variant, the
  further --configs) with each number of seeds, written to --out."""
  import benchmarks as bench
  from benchmarks import online_seeds
  spec = _CONFIGS.value[0]
  with cli.one_line_errors():
    variants = online_seeds.parse_variants(configs[spec], _VARIANT.value) + [
        (other, online_seeds.fields_differing(configs[spec], configs[other], other))
        for other in _CONFIGS.value[1:]]  # Each further config: a variant of the first.
  overlaps = {'on': (True,), 'off': (False,), 'both': (True, False)}[_ONLINE_OVERLAP.value]
  entries = online_seeds.benchmark_seeds(configs[spec], seeds, _ONLINE_STEPS.value,
                                         overlaps=overlaps,
                                         seed_devices=[int(d) for d in _ONLINE_DEVICES.value],
                                         variants=variants)
  table = online_seeds.markdown(entries, spec, _ONLINE_STEPS.value, device['name'])
  print(table)
  bench.write_results(_OUT.value, [dict(e, device=device) for e in entries], table)


def _update_split(configs: dict, device: dict) -> None:
  """--update_split: the first config's update FLOPs with each part left out, written to --out."""
  import benchmarks as bench
  from benchmarks import update_split
  spec = _CONFIGS.value[0]
  entries = update_split.split(configs[spec], update_split.update_gflop)
  table = update_split.markdown(entries, spec)
  print(table)
  bench.write_results(_OUT.value, [dict(e, device=device) for e in entries], table)


OVERRIDES = []  # 'field=value' items of --config.field=value, for every config.


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)  # Keep orbax's per-save INFO lines out of the output.
  with cli.one_line_errors():
    seeds, breakdown, devices = _check_flags()
  if breakdown:  # One device per seed, as runs train by default.
    devices = max(devices, *breakdown)
  if seeds and 0 in cli.int_list('--online_seed_devices', _ONLINE_DEVICES.value):  # One a seed.
    devices = max(devices, *seeds)
  if (_ONLINE_SEEDS.value or _BREAKDOWN.value) and devices > 1:  # Before JAX starts: the CPU as that many devices.
    import jax
    jax.config.update('jax_num_cpu_devices', devices)
  import benchmarks as bench
  from benchmarks import hardware, training
  with cli.one_line_errors():
    configs = _load_configs(online=bool(seeds or breakdown))
  device = hardware.device_info()
  if _SPLIT.value:
    _update_split(configs, device)
    return
  print(f"device: {device['name']} x {device['device_count']}; load average "
        f"{device['loadavg_1min_at_start']:.2f}")
  if _BREAKDOWN.value:
    from benchmarks import online_breakdown
    spec = _CONFIGS.value[0]
    peak = hardware.measure_peak(_PEAK_SIZE.value, _PEAK_REPEATS.value)
    entries = online_breakdown.run(configs[spec], breakdown,
                                   _WAVES.value, peak, _REPEATS.value)
    table = online_breakdown.markdown(entries, spec, device['name'])
    print(table)
    bench.write_results(_OUT.value, [dict(e, device=device) for e in entries], table)
    return
  if _ONLINE_SEEDS.value:
    _online_seeds(configs, seeds, device)
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
