"""The disk-full probes of benchmarks.fault_injection (issue 72): a run whose workdir's disk
fills up mid-run must stop on one line naming the full disk, its newest checkpoint intact; once
space is freed, the same command must resume to the uninterrupted run's final TrainState.

The workdir lies on a tmpfs mounted for the trial (root only: `mount -t tmpfs`; a loop device
would need mount as well, so there is no fallback): either a small one (20-95% of the
uninterrupted run's workdir size; it fills while a checkpoint is written) or a roomy one that
another file fills from a random moment on (any write can then fail). Run through
`python -m benchmarks.fault_injection --disk_full=N --disk_filled=N`.
"""

import os
import random
import re
import signal
import subprocess
import time
from typing import Any, Dict, List

from benchmarks.fault_runner import (Runner, commands, complete_steps, judge, read_stderr,
                                     restored, verdict)


def mount_disk(path: str, kib: int, remount: bool = False) -> None:
  """A tmpfs of `kib` KiB at `path` (or the one there resized); needs root. RuntimeError saying
  why when mount refuses (no fallback: a loop device needs mount as well)."""
  os.makedirs(path, exist_ok=True)
  cmd = (['mount', '-o', f'remount,size={kib}k', path] if remount else
         ['mount', '-t', 'tmpfs', '-o', f'size={kib}k', 'tmpfs', path])
  got = subprocess.run(cmd, capture_output=True, text=True)
  if got.returncode:
    raise RuntimeError(f"{' '.join(cmd)} failed ({got.stderr.strip()}): the disk-full probe "
                       'needs root; without it, pass --disk_full=0 --disk_filled=0')


def first_stop(first: Dict[str, Any], workdir: str) -> Dict[str, Any]:
  """The run on the small disk: stopped on one line naming the full disk (and where), or not."""
  line = first['errors'][0] if len(first['errors']) == 1 else ''
  named = line.startswith('error: no space left on the device')
  found = re.search(r'\(writing (\S+)\)', line)
  where = found.group(1) if found else 'a file it does not name'  # Relative to the workdir.
  where = (os.path.relpath(where, workdir) if os.path.isabs(where) else where).split(os.sep)[:2]
  ok = first['rc'] != 0 and named and not first['traceback']
  outcome = ('finished (the disk did not fill)' if first['rc'] == 0 else
             f"stopped (exit {first['rc']}, "
             f"{'one line naming the full disk' if ok else 'NOT one line'}, writing "
             f"{'/'.join(where)})")
  return dict(first_rc=first['rc'], first_traceback=first['traceback'],
              first_errors=first['errors'], first_stop_ok=ok, first_outcome=outcome)


def disk_full_trial(runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random):
  """A run of ref's kind into a workdir on a tmpfs of 20-95% of the uninterrupted run's final
  workdir size (it fills up mid-run); then the tmpfs grows (space freed) and the same command
  runs again, judged as a resume."""
  kind = ref['kind']
  name = f'{kind}_disk_full_{index}'
  mount = os.path.join(runner.scratch, name)
  subprocess.run(['umount', mount], capture_output=True, check=False)
  kib = int(rng.uniform(0.2, 0.95) * ref['kib'])
  mount_disk(mount, kib)
  try:
    workdir = os.path.join(mount, 'workdir')
    cmd = commands(kind, workdir, runner.scratch)
    first = first_stop(runner.run(cmd, name), workdir)
    before, kept = complete_steps(workdir), restored(workdir, ref)
    mount_disk(mount, 4 * ref['kib'], remount=True)
    rerun = runner.run(cmd, name + '_rerun')
    row = dict(kind=kind, fault=f'disk full ({kib} KiB tmpfs)', disk_kib=kib, **first,
               point=f'checkpoints at the stop: {before or "none"}', steps_before_rerun=before,
               **kept, **judge(workdir, before, rerun, ref))
  finally:
    subprocess.run(['umount', mount], capture_output=True, check=False)
  row['ok'] = verdict(row)
  return row


def top_up(ballast: str, margin_kib: int) -> None:
  """Appends zeros to `ballast` until its disk has at most `margin_kib` KiB free."""
  stat = os.statvfs(os.path.dirname(ballast))
  extra = stat.f_bavail * stat.f_frsize - margin_kib * 1024
  if extra > 0:
    try:
      with open(ballast, 'ab') as f:
        f.write(b'\0' * extra)
    except OSError:  # Full already: what was written stays.
      pass


def run_filled(runner: Runner, cmd: List[str], name: str, ballast: str, delay: float,
               margin_kib: int) -> Dict[str, Any]:
  """`Runner.run`, another file filling the disk from `delay` seconds on (kept topped up to
  `margin_kib` KiB free until the run ends, as another program writing there would)."""
  start = time.perf_counter()
  proc = runner.start(cmd, name)
  while proc.poll() is None and time.perf_counter() - start < runner.timeout:
    if time.perf_counter() - start >= delay:
      top_up(ballast, margin_kib)
    time.sleep(0.02)
  if proc.poll() is None:
    os.killpg(proc.pid, signal.SIGKILL)  # The group this runner started.
  rc = proc.wait()
  with open(runner.log(name)) as f:
    return dict(rc=rc, seconds=round(time.perf_counter() - start, 1), **read_stderr(f.read()))


def disk_filled_trial(runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random):
  """A run of ref's kind on a roomy tmpfs that another file fills, from a random moment
  (3-97% of the uninterrupted run's wall time) to 0-64 KiB free; then that file goes and the
  same command runs again, judged as a resume."""
  kind = ref['kind']
  name = f'{kind}_disk_filled_{index}'
  mount = os.path.join(runner.scratch, name)
  subprocess.run(['umount', mount], capture_output=True, check=False)
  mount_disk(mount, 4 * ref['kib'])
  delay, margin = rng.uniform(0.03, 0.97) * ref['duration'], rng.randint(0, 64)
  try:
    workdir, ballast = os.path.join(mount, 'workdir'), os.path.join(mount, 'ballast')
    cmd = commands(kind, workdir, runner.scratch)
    first = first_stop(run_filled(runner, cmd, name, ballast, delay, margin), workdir)
    before, kept = complete_steps(workdir), restored(workdir, ref)
    if os.path.exists(ballast):  # The space freed.
      os.remove(ballast)
    rerun = runner.run(cmd, name + '_rerun')
    row = dict(kind=kind, fault=f'disk filled by another file at {delay:.1f} s ({margin} KiB '
               'left)', disk_kib=4 * ref['kib'], fill_s=round(delay, 2), margin_kib=margin,
               **first, point=f'checkpoints at the stop: {before or "none"}',
               steps_before_rerun=before, **kept, **judge(workdir, before, rerun, ref))
  finally:
    subprocess.run(['umount', mount], capture_output=True, check=False)
  row['ok'] = verdict(row)
  return row
