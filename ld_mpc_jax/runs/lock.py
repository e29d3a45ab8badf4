"""An exclusive lock per run directory: two processes never train into one workdir."""

import contextlib
import os
from typing import Iterator

from ld_mpc_jax.learn.checkpointing import WorkdirError


LOCK_FILE = '.lock'


class WorkdirBusyError(WorkdirError):
  """Another live process holds the workdir's lock (one line naming its pid, exit code 2)."""


@contextlib.contextmanager
def workdir_lock(workdir: str) -> Iterator[None]:
  """Holds an exclusive lock on `workdir` (<workdir>/.lock, `fcntl.flock`) inside the block.

  A second process on the same workdir raises WorkdirBusyError at once, naming the holder's pid.
  The kernel releases the lock whenever the holder exits, a SIGKILL included, so a lock file
  left behind is stale by construction and is simply taken over. A workdir this call created
  is removed again when nothing but the lock was written to it (a run refused at its checks).
  """
  import fcntl  # pylint: disable=g-import-not-at-top (POSIX only; imported where used)
  created = not os.path.exists(workdir)
  try:
    os.makedirs(workdir, exist_ok=True)
  except OSError as err:  # A file there or above it, a read-only or virtual file system.
    raise WorkdirError(f'--workdir={workdir} cannot be a run directory: '
                       f'{err.strerror or err}') from None
  path = os.path.join(workdir, LOCK_FILE)
  while True:
    try:
      fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as err:  # A folder this process may not write into.
      raise WorkdirError(f'--workdir={workdir} cannot be a run directory: cannot write '
                         f'{path} ({err.strerror or err})') from None
    try:
      fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
      with os.fdopen(fd) as f:
        holder = f.read().strip() or 'unknown'
      raise WorkdirBusyError(f'{workdir} is in use by another run (pid {holder}, lock '
                             f'{path}): wait for it to finish or choose another --workdir'
                             ) from None
    try:  # The file may have been removed by its last holder between our open and flock.
      same = os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
      same = False
    if same:
      break
    os.close(fd)
  try:
    os.ftruncate(fd, 0)
    os.write(fd, f'{os.getpid()}\n'.encode())
    yield
  finally:
    try:
      os.remove(path)
    except OSError:
      pass
    os.close(fd)
    if created:
      try:
        os.rmdir(workdir)  # Only when empty: nothing of the run was written.
      except OSError:
        pass
