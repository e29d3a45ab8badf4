r"""Trains and evaluates LD-MPC: one run (one training seed, or `train.num_seeds` in one process).

  python -m experiments.train --config=mt10.py:cpu --workdir=runs/mt10_cpu   # one agent, MT10
  python -m experiments.train --config=door_open.py:cpu --workdir=runs/door_open_tdmpc2 \
      --config.data.source=tdmpc2 --config.data.path='mt80/chunk_*.pt'   # TD-MPC2's data
  python -m experiments.train --config=door_open.py --workdir=runs/door_open_dp \
      --config.train.data_parallel=True     # batch split over all devices (docs/scaling.md)
"""

import os
import signal
import sys

from absl import flags, logging
from ml_collections import config_flags

from ld_mpc_jax.cli import errors as cli

_CONFIG = config_flags.DEFINE_config_file('config', None, 'Config file (optionally :preset).',
                                          lock_config=True)
_WORKDIR = flags.DEFINE_string('workdir', None, 'Run directory (checkpoints, logs, report).')
_QUIET = flags.DEFINE_bool('quiet', False, 'No stage lines (data, compiling, evaluating at step '
                           'N, resumed, what was written) on stderr.')
_CONTINUE = flags.DEFINE_bool('continue_with_changes', False, 'Continue the run in --workdir '
                              'although its config.json differs from this config (kept as '
                              'config.<n>.json); without it such a workdir is refused.')
# Several processes (hosts) training one model: docs/scaling.md. None: detected from the cluster
# environment (SLURM, Open MPI, Cloud TPU) by jax.distributed.initialize.
_DISTRIBUTED = flags.DEFINE_bool('distributed', False, 'Call jax.distributed.initialize first.')
_COORDINATOR = flags.DEFINE_string('coordinator_address', None, 'host:port of process 0.')
_NUM_PROCESSES = flags.DEFINE_integer('num_processes', None, 'Number of processes.')
_PROCESS_ID = flags.DEFINE_integer('process_id', None, 'This process, 0..num_processes-1.')
flags.mark_flags_as_required(['config', 'workdir'])


def _on_interrupt(signum, frame):
  """SIGINT: remembered (`progress.INTERRUPTED`, checked after every step of the run, so that an
  interrupt a library swallows still stops it), then raised as usual."""
  del signum, frame
  from ld_mpc_jax.runs import progress  # pylint: disable=g-import-not-at-top
  progress.INTERRUPTED.set()
  if not progress.SAVING.is_set():  # Else the loop stops once the checkpoint is complete.
    raise KeyboardInterrupt


def _interrupted(workdir: str):
  """One line, exit code 130; the library's worker threads, cut short, stay quiet."""
  import threading  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.runs.progress import interrupted_message  # pylint: disable=g-import-not-at-top
  threading.excepthook = lambda args: None
  sys.unraisablehook = lambda args: None
  print(f'\n{interrupted_message(workdir)}', file=sys.stderr, flush=True)
  sys.exit(130)


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)  # Keep orbax's per-save INFO lines out of the log.
  import jax
  from ld_mpc_jax.ops.seed_groups import cpu_devices_wanted
  try:
    t = _CONFIG.value.train
  except OSError as err:  # A config file that failed to load (ml_collections defers the error).
    flag = flags.FLAGS['config']
    cli.fail(cli.config_file_error('--config', flag.serialize().partition('=')[2], err))
  devices = t.get('seed_devices', 1)
  if isinstance(devices, int) and cpu_devices_wanted(t.num_seeds, devices) > 1:  # Before JAX
    # starts: the CPU as one device per group of seeds (train.seed_devices).
    jax.config.update('jax_num_cpu_devices', cpu_devices_wanted(t.num_seeds, devices))
  if _DISTRIBUTED.value:  # Before anything touches a device.
    jax.distributed.initialize(coordinator_address=_COORDINATOR.value,
                               num_processes=_NUM_PROCESSES.value, process_id=_PROCESS_ID.value)
  from ld_mpc_jax.learn.checkpointing import WorkdirError
  from ld_mpc_jax.runs.checks import checked_plans
  from ld_mpc_jax.data import DatasetError
  from ld_mpc_jax.runs.train import train_and_evaluate
  try:  # Bad input: one line and exit code 2, before anything is collected or compiled.
    cli.check_workdir(_WORKDIR.value)
    checked_plans(_CONFIG.value, _WORKDIR.value)  # What train_and_evaluate checks first.
  except (ValueError, OSError) as err:  # OSError: a config file that failed to load (deferred).
    cli.fail(' '.join(str(err).split()))
  from ld_mpc_jax.runs import progress
  if _QUIET.value:
    progress.QUIET.set()
  sys.unraisablehook = progress.quiet_unraisable(sys.unraisablehook)
  signal.signal(signal.SIGINT, _on_interrupt)
  try:
    train_and_evaluate(_CONFIG.value, _WORKDIR.value, _CONTINUE.value)
  except (DatasetError, WorkdirError) as err:  # Data that do not fit, another run's workdir.
    print(f'error: {err}', file=sys.stderr)
    sys.exit(2)
  except KeyboardInterrupt:  # Ctrl-C: one line, what is kept, exit code 130.
    _interrupted(_WORKDIR.value)
  if progress.INTERRUPTED.is_set():  # Swallowed somewhere (a library's thread or callback).
    _interrupted(_WORKDIR.value)
  if jax.process_index() == 0:  # The one process that writes the report.
    name = 'report.md' if _CONFIG.value.train.num_seeds == 1 else 'pooled.md'
    print(open(os.path.join(_WORKDIR.value, name)).read())
