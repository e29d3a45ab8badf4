"""Online training throughput against the number of training seeds in one run
(`train.num_seeds`, ld_mpc_jax.runs.online): environment steps and updates per second of each seed,
and the wall time of N seeds against one, measured in the same process one after the other.

With `overlaps` (True, False) each N also runs with every update waiting for the environment
steps that call for it (the loop before the updates were dispatched ahead of the steps: the same
updates, so the ratio is the gain of taking the environment loop off the critical path).

Each N trains `env_steps` from scratch in a temporary workdir with evaluation off; the rate is
taken over the waves after `skip` waves (the first acting waves compile the planner and the
update), from each run's own online.csv (one row per wave, env_steps_per_s of the wave).
"""

import os
import statistics
import tempfile
import time
from typing import Dict, List, Sequence, Tuple

import ml_collections

from ld_mpc_jax.configs.overrides import parse_variant, with_overrides


def _wave_rates(workdir: str, skip: int) -> List[float]:
  from ld_mpc_jax.eval import run_files  # pylint: disable=g-import-not-at-top
  rows = run_files.read_csv(os.path.join(workdir, run_files.ONLINE_CSV))
  return [float(r['env_steps_per_s']) for r in rows[skip:] if r['acting'] != 'random']


def _run(c: ml_collections.ConfigDict, overlap: bool, skip: int):
  """(wall seconds, acting waves' rates) of one online run; without `overlap` every update
  waits for the steps that call for it."""
  from ld_mpc_jax.runs import train  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.online import seats as online_seats  # pylint: disable=g-import-not-at-top
  upcoming = online_seats.SeatWave.upcoming
  try:
    if not overlap:
      online_seats.SeatWave.upcoming = lambda self: 0
    with tempfile.TemporaryDirectory() as workdir:
      start = time.perf_counter()
      train.train_and_evaluate(c, workdir)
      wall = time.perf_counter() - start
      first = workdir if c.train.num_seeds == 1 else os.path.join(workdir, f'seed{c.seed}')
      return wall, _wave_rates(first, skip)
  finally:
    online_seats.SeatWave.upcoming = upcoming


def parse_variants(config: ml_collections.ConfigDict, texts: Sequence[str]):
  """[(name, {field: value})] of --online_variant texts (NAME:field=value,...), each checked
  on `config` (a one-line ValueError for an unknown field or a bad value) before anything runs."""
  from ld_mpc_jax.runs.checks import validate_config  # pylint: disable=g-import-not-at-top
  variants = [parse_variant(text) for text in texts]
  for _, fields in variants:
    validate_config(with_overrides(config, fields))
  return variants


def fields_differing(base: ml_collections.ConfigDict, other: ml_collections.ConfigDict,
                     name: str = 'the config') -> dict:
  """{dotted field: other's value} where `other` differs from `base`, so that
  with_overrides(base, fields) is `other`: another preset timed as a variant of the first. A
  ValueError names a field that `base` lacks (not a variant of it)."""
  def flat(d, prefix=''):
    out = {}
    for k, v in d.items():
      if isinstance(v, dict):
        out.update(flat(v, f'{prefix}{k}.'))
      else:
        out[f'{prefix}{k}'] = v
    return out
  a, b = flat(base.to_dict()), flat(other.to_dict())
  extra = sorted(set(b) - set(a))
  if extra:
    raise ValueError(f'{name} has fields the first --configs lacks ({", ".join(extra[:3])}): '
                     'only presets of one config file time as variants of each other')
  return {k: v for k, v in b.items() if a[k] != v}


def benchmark_seeds(config: ml_collections.ConfigDict, seeds: Sequence[int], env_steps: int,
                    skip: int = 1, overlaps: Sequence[bool] = (True,),
                    seed_devices: Sequence[int] = (1,),
                    variants: Sequence[Tuple[str, dict]] = ()) -> List[Dict[str, float]]:
  """One entry per N in `seeds` (and per setting of `overlaps`, updates dispatched ahead of the
  steps or not, and per number of devices the seeds are spread over, `train.seed_devices`,
  skipped where it exceeds N unless N is 1; 0: one device per seed, as runs train by default):
  wall seconds of the whole run (compilation included), the median environment steps per second of one seed over its acting waves after
  `skip`, the updates per second that implies (`online.update_ratio` x that, per seed), and both summed over the N seeds.

  `variants` ((name, {field: value}), ...): each setting also runs with each variant's fields
  set, right after the config as given (variant 'base'), so that their ratio is measured in one
  process under the same load."""
  out = []
  settings = [(n, overlap, d) for n in seeds for overlap in overlaps for d in seed_devices
              if d <= n or d == min(seed_devices)]
  runs = [(s, v) for s in settings for v in [('base', {})] + list(variants)]
  for (n, overlap, devices), (variant, fields) in runs:
    c = with_overrides(config, fields)
    c.train.num_seeds, c.online.env_steps = n, env_steps
    c.train.seed_devices = min(devices, n) or n
    c.online.eval_every = c.online.checkpoint_every = env_steps
    c.eval.episodes = 0
    wall, rates = _run(c, overlap, skip)
    rate = statistics.median(rates) if rates else float('nan')
    if variant == 'base':  # Runs first in its setting: the variants' rates are against it.
      base_rate = rate
    out.append(dict(variant=variant, num_seeds=n, overlap=overlap, seed_devices=c.train.seed_devices,
                    wall_s=wall, waves_timed=len(rates), env_steps_per_s_per_seed=rate,
                    updates_per_s_per_seed=rate * c.online.update_ratio,
                    env_steps_per_s_all_seeds=rate * n, rate_vs_base=rate / base_rate))
  base = out[0]['env_steps_per_s_per_seed']
  for e in out:  # Time of N seeds' steps against one seed's, from the steady rates.
    e['time_ratio_vs_first'] = base / e['env_steps_per_s_per_seed']
  return out


def markdown(entries: List[Dict[str, float]], spec: str, env_steps: int, device: str) -> str:
  lines = [f'Online training, {spec}, {env_steps:,} environment steps per seed (simulator steps), '
           f'on {device}; median over acting waves after the first.', '',
           '| variant | seeds in one run | devices they are spread over | updates dispatched ahead of the '
           'steps | env steps/s per seed | updates/s per seed | env steps/s, all seeds | time of '
           'the run per env step vs the first row | steps/s vs base | wall s (with compile) |',
           '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |']
  lines += [f"| {e.get('variant', 'base')} | {e['num_seeds']} | {e.get('seed_devices', 1)} | "
            f"{'yes' if e.get('overlap', True) else 'no'} | "
            f"{e['env_steps_per_s_per_seed']:.1f} | "
            f"{e['updates_per_s_per_seed']:.1f} | {e['env_steps_per_s_all_seeds']:.1f} | "
            f"{e['time_ratio_vs_first']:.2f} | {e.get('rate_vs_base', 1.0):.2f} | "
            f"{e['wall_s']:.0f} |" for e in entries]
  return '\n'.join(lines) + '\n'
