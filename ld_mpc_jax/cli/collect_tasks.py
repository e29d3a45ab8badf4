r"""Collects (or loads from the cache) every task's scripted dataset of a config, and measures it.

  python -m experiments.collect tasks --config=mt10.py:cpu

The datasets are those `experiments.train` uses for the same config (same presets, cache files
under config.data.dir). Prints one line per task (episodes, transitions, episode success rate
overall and at each noise level of the preset, mean return, collection seconds) and writes them
as JSON with --out.
"""

import json
import sys

from absl import app, flags
from ml_collections import config_flags


_CONFIG = config_flags.DEFINE_config_file('config', None, 'Config file (optionally :preset).',
                                          lock_config=True)
_OUT = flags.DEFINE_string('out', None, 'Optional JSON file for the per-task summary.')
flags.mark_flags_as_required(['config'])


def main(argv):
  del argv
  from ld_mpc_jax.model import tasks
  from ld_mpc_jax.data import collection, sources
  config = _CONFIG.value
  try:  # Bad input: one line and exit code 2.
    config_tasks = tasks.Tasks.from_config(config)
    config_tasks.check()
    spec = sources.DataSpec.from_config(config)
    spec.check()
  except ValueError as err:
    print(f'error: {err}', file=sys.stderr)
    sys.exit(2)
  rows = {}
  for name in config_tasks.names:
    try:  # An unknown preset or a dataset that does not fit the config: one line too.
      ds = sources.load_dataset(spec.for_task(name))
    except ValueError as err:
      print(f'error: {err}', file=sys.stderr)
      sys.exit(2)
    rows[name] = dict(**collection.summary(ds),
                      success_per_level=collection.success_per_level(ds),
                      collection_seconds=ds.metadata.get('collection_seconds'))
    levels = ', '.join('-' if v is None else f'{v:.2f}'  # '-': no episode at that level.
                       for v in rows[name]['success_per_level'].values())
    print(f"{name}: {ds.num_episodes} episodes, {ds.num_transitions} transitions, success "
          f"{rows[name]['success_rate']:.3f} (per level: {levels}), mean return "
          f"{rows[name]['mean_return']:.1f}", flush=True)
  if _OUT.value:
    with open(_OUT.value, 'w') as f:
      json.dump(rows, f, indent=1)
