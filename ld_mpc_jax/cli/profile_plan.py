"""Where the time of one `plan` call (or training update) goes: XLA ops by network and kind.

  python -m experiments.diagnose profile                          # reference config, 3 traced calls
  python -m experiments.diagnose profile --config=door_open.py:cpu --calls=5 --out=profile.json
  python -m experiments.diagnose profile --config=door_open.py:cpu --target=update

Traces `--calls` calls of the jitted plan, or with --target=update of the training update on a
synthetic batch (random parameters, after compilation and one warm-up)
with jax.profiler and prints, in ms per call, the time of the XLA ops grouped by network and by
kind of work (benchmarks/profiling.py); writes the numbers as JSON with --out. Method:
docs/benchmark.md.
"""

import json
import os
import sys

from absl import app, flags
from ml_collections import config_flags

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import CONFIG_DIR

_CONFIG = config_flags.DEFINE_config_file(
    'config', os.path.join(CONFIG_DIR, 'door_open.py'), 'Config file (optionally :preset).',
    lock_config=True)
_CALLS = flags.DEFINE_integer('calls', 3, 'Traced calls (after one warm-up call).')
_TARGET = flags.DEFINE_enum('target', 'plan', ['plan', 'update'],
                            'What to profile: the planner or one training update.')
_OUT = flags.DEFINE_string('out', None, 'JSON output (optional).')


def main(argv):
  del argv
  from benchmarks import profiling
  from ld_mpc_jax.runs.checks import validate_config
  with cli.one_line_errors():
    validate_config(_CONFIG.value)
    if _CALLS.value < 1:
      raise ValueError(f'--calls must be >= 1, got {_CALLS.value}')
  profile = profiling.profile_plan if _TARGET.value == 'plan' else profiling.profile_update
  result = profile(_CONFIG.value, _CALLS.value)
  print(profiling.markdown(result))
  if _OUT.value:
    with open(_OUT.value, 'w') as f:
      json.dump(result, f, indent=2)
    print(f'wrote {_OUT.value}')
