"""Runs command lines of experiments/ in forks of one process that has already imported the heavy
libraries, so that a table of mistakes costs one import of JAX, not one per line.

  python tests/cli_probes.py CWD < probes.json > results.json

stdin: a JSON list of argv lists (argv[0] is the command, e.g. 'train'). stdout: a JSON list of
{'code': exit code, 'stderr': text} in the same order. Each line runs as
`python -m experiments.<command> <args>` would, from CWD, in a child forked before any JAX backend
starts (so the fork is safe), with a 120 s limit."""

import io
import json
import os
import runpy
import signal
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _preload():
  """The libraries every command imports, without starting a backend or defining a flag."""
  import absl.app, absl.flags, jax, flax.linen, ml_collections, numpy, optax  # noqa: F401,E401
  import orbax.checkpoint  # noqa: F401
  from ld_mpc_jax.configs import resolve_config_arg  # noqa: F401


def _child(argv, out_fd):
  os.dup2(out_fd, 1)
  os.dup2(out_fd, 2)
  sys.stdout = io.TextIOWrapper(os.fdopen(1, 'wb', buffering=0), write_through=True)
  sys.stderr = io.TextIOWrapper(os.fdopen(2, 'wb', buffering=0), write_through=True)
  sys.argv = [f'experiments/{argv[0]}.py', *argv[1:]]
  code = 0
  try:
    runpy.run_module(f'experiments.{argv[0]}', run_name='__main__', alter_sys=True)
  except SystemExit as exit_:
    code = exit_.code if isinstance(exit_.code, int) else (0 if exit_.code is None else 1)
  except BaseException:  # pylint: disable=broad-except
    import traceback  # pylint: disable=g-import-not-at-top
    traceback.print_exc()
    code = 1
  sys.stdout.flush()
  sys.stderr.flush()
  os._exit(code)  # pylint: disable=protected-access


def run(argv, cwd, limit=120):
  """{'code', 'stderr'} of one command line (stdout and stderr together)."""
  with tempfile.TemporaryFile() as out:
    pid = os.fork()
    if pid == 0:
      os.chdir(cwd)
      signal.alarm(limit)
      _child(argv, out.fileno())
    _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    out.seek(0)
    return {'code': code, 'stderr': out.read().decode(errors='replace')}


if __name__ == '__main__':
  sys.path.insert(0, REPO)
  _preload()
  probes = json.load(sys.stdin)
  json.dump([run(p, sys.argv[1]) for p in probes], sys.stdout)
