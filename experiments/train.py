"""Trains and evaluates LD-MPC.

  python -m experiments.train --config=door_open.py:cpu --workdir=runs/door_open_cpu

A bare config name resolves to experiments/configs/<name>; `:preset` selects a preset; any field
can be overridden, e.g. --config.task=drawer-open-v3 --config.train.num_steps=2000.
"""

import os
import sys

from absl import app, flags, logging
from ml_collections import config_flags

from experiments.configs import resolve_config_arg

_CONFIG = config_flags.DEFINE_config_file('config', None, 'Config file (optionally :preset).',
                                          lock_config=True)
_WORKDIR = flags.DEFINE_string('workdir', None, 'Run directory (checkpoints, logs, report).')
flags.mark_flags_as_required(['config', 'workdir'])


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)  # Keep orbax's per-save INFO lines out of the log.
  from ld_mpc_jax.config_checks import validate_config
  from ld_mpc_jax.envs import check_task
  from ld_mpc_jax.train import train_and_evaluate
  try:  # Bad input: one line and exit code 2, before anything is collected or compiled.
    validate_config(_CONFIG.value)
    check_task(_CONFIG.value.task)
  except ValueError as err:
    print(f'error: {err}', file=sys.stderr)
    sys.exit(2)
  train_and_evaluate(_CONFIG.value, _WORKDIR.value)
  print(open(os.path.join(_WORKDIR.value, 'report.md')).read())


if __name__ == '__main__':
  sys.argv = resolve_config_arg(sys.argv)
  app.run(main)
