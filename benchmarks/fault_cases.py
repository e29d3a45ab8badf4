"""The faults of issue 102 in benchmarks.fault_injection: Ctrl-C (SIGINT to the process group, as a
terminal sends it) at random moments, a second copy of the same command on the same workdir,
crafted TD-MPC2 chunk files whose unpickling would run a shell command, and evaluate's and
collect's result written onto a full disk.

  python -m benchmarks.fault_injection --kills=0 --damages=0 --disk_full=0 --interrupts=5 \
      --twins=3 --pickles=6 --outputs_full=4 --pickle_python=PYTHON_WITH_TORCH \
      --out=results/faults/faults_102.json

- Interrupt: exit code 130, no traceback, the last line `interrupted: ...` (or the run had
  finished), then the same command resumes to the uninterrupted run's final TrainState.
- Twin: the second copy exits 2 within 30 s on one line naming the first's pid and writes
  nothing; the first ends on the uninterrupted run's final TrainState, no CSV row twice.
- Pickle: `experiments.train --config.data.source=tdmpc2 --config.data.path=EVIL.pt` exits 2 on
  one line and the payload's marker file does not exist. The chunk loader needs torch and
  tensordict: `--pickle_python` names an interpreter that has them (with this checkout on its
  path); with the project's own (no torch) the run stops at the missing extra, which the row says.
- Output on a full disk (root: a tmpfs): exit 1 on one line naming the full disk, no file left.
"""

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from typing import Any, Dict

from benchmarks.fault_runner import (Runner, commands, complete_steps, judge, phase, read_stderr,
                                     restored, total_of)

# (module, name) a crafted chunk names, and the pickle opcode that looks it up.
PAYLOADS = [('numpy.f2py', 'os.system', 'stack'), ('os', 'system', 'global'),
            ('builtins', 'eval', 'global'), ('posix', 'system', 'stack'),
            ('subprocess', 'getoutput', 'stack'), ('numpy.testing', 'os.system', 'stack')]


def interrupt_ok(row: Dict[str, Any]) -> bool:
  """The interrupt reached a running run, which stopped on one clean line (exit 130), and the
  rerun ended on the uninterrupted run's final TrainState (a checkpoint it restored too)."""
  return (row['first_rc'] == 130 and bool(row['first_stop_ok']) and row['rc'] == 0
          and bool(row['identical']) and row.get('restored_as_reference') is not False)


def twin_ok(row: Dict[str, Any]) -> bool:
  """The second copy met a running first one and was refused at once on one line naming its
  pid; the first ended on the uninterrupted run's final TrainState with no CSV row twice."""
  refused = row.get('second_refused', (  # Rows written before the field: from what they hold.
      'first running' in row['point'] and row['second_rc'] == 2 and row['second_s'] < 30
      and len(row['second_errors']) == 1 and 'pid ' in row['second_errors'][0]
      and not row['second_traceback']))
  return bool(refused) and row['rc'] == 0 and bool(row['identical']) and not row['rows_twice']


def pickle_ok(row: Dict[str, Any]) -> bool:
  """The crafted chunk reached the restricted unpickler (torch installed), which refused it on
  one line (exit 2); the payload's marker file does not exist."""
  return row['rc'] == 2 and bool(row['one_line']) and bool(row['torch_checked']) and not (
      row['payload_ran'])


def output_ok(row: Dict[str, Any]) -> bool:
  """The full disk stopped the command on one line naming it (exit 1), nothing left there."""
  return (row['rc'] == 1 and bool(row['one_line']) and 'space' in ' '.join(row['errors'])
          and not row['left'])


# group (fault_injection.group_of) -> the verdict of its trials.
VERDICTS = {'interrupt': interrupt_ok, 'twin': twin_ok, 'pickle': pickle_ok,
            'output disk full': output_ok}


def _last_line(text: str) -> str:
  lines = [l.strip() for l in text.replace('\r', '\n').splitlines() if l.strip()]
  return lines[-1] if lines else ''


def _started(runner: Runner, ref: Dict[str, Any], what: str, index: int, delay: float):
  """A fresh run of ref's kind into its own workdir, `delay` seconds on (or ended sooner):
  (name, workdir, command, process, start time)."""
  name = f"{ref['kind']}_{what}_{index}"
  workdir = os.path.join(runner.scratch, name)
  shutil.rmtree(workdir, ignore_errors=True)
  cmd = commands(ref['kind'], workdir, runner.scratch)
  start = time.perf_counter()
  proc = runner.start(cmd, name)
  while proc.poll() is None and time.perf_counter() < start + delay:
    time.sleep(0.02)
  return name, workdir, cmd, proc, start


def interrupt_trial(runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random):
  """SIGINT to a fresh run of ref's kind at a random moment, then the same command again."""
  kind = ref['kind']
  delay = rng.uniform(0.03, 0.97) * ref['duration']
  name, workdir, cmd, proc, start = _started(runner, ref, 'interrupt', index, delay)
  sent, where = proc.poll() is None, 'finished before the interrupt'
  if sent:
    with open(runner.log(name)) as f:
      where = phase(workdir, f.read(), total_of(kind))
    os.killpg(proc.pid, signal.SIGINT)
  try:
    rc = proc.wait(timeout=120)
  except subprocess.TimeoutExpired:  # The interrupt did not stop it.
    os.killpg(proc.pid, signal.SIGKILL)
    rc = proc.wait()
  with open(runner.log(name)) as f:
    text = f.read()
  last = _last_line(text)
  first_ok = sent and rc == 130 and 'Traceback' not in text and last.startswith('interrupted')
  before, kept = complete_steps(workdir), restored(workdir, ref)
  rerun = runner.run(cmd, name + '_rerun')
  row = dict(kind=kind, fault='SIGINT (Ctrl-C)', delay_s=round(delay, 2), first_rc=rc,
             first_traceback='Traceback' in text, first_line=last[:200], first_stop_ok=first_ok,
             point=f'{time.perf_counter() - start:.1f} s: {where}', steps_before_rerun=before,
             **kept, **judge(workdir, before, rerun, ref))
  row['outcome'] = (f"exit {rc}, {'one line' if first_ok else 'NOT one clean line'}; then "
                    + row['outcome'])
  row['ok'] = interrupt_ok(row)
  shutil.rmtree(workdir, ignore_errors=True)
  return row


def _rows_twice(workdir: str) -> int:
  """CSV rows that appear more than once in any CSV of the workdir (duplicate appends)."""
  twice = 0
  for folder, _, files in os.walk(workdir):
    for name in files:
      if name.endswith('.csv'):
        with open(os.path.join(folder, name)) as f:
          lines = f.read().splitlines()
        twice += len(lines) - len(set(lines))
  return twice


def twin_trial(runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random):
  """The same command started again on the same workdir while the first runs."""
  kind = ref['kind']
  delay = rng.uniform(0.05, 0.6) * ref['duration']
  name, workdir, cmd, first, start = _started(runner, ref, 'twin', index, delay)
  running = first.poll() is None
  second = runner.run(cmd, name + '_second')
  try:
    rc = first.wait(timeout=runner.timeout)
  except subprocess.TimeoutExpired:
    os.killpg(first.pid, signal.SIGKILL)
    rc = first.wait()
  with open(runner.log(name)) as f:
    first_out = dict(rc=rc, seconds=round(time.perf_counter() - start, 1), **read_stderr(f.read()))
  refused = (running and second['rc'] == 2 and len(second['errors']) == 1
             and not second['traceback'] and f'pid {first.pid}' in second['errors'][0]
             and second['seconds'] < 30)
  row = dict(kind=kind, fault='a second copy on the same workdir', delay_s=round(delay, 2),
             point=f"{delay:.1f} s: {'first running' if running else 'first finished'}",
             second_rc=second['rc'], second_s=second['seconds'], second_errors=second['errors'],
             second_refused=refused,
             second_traceback=second['traceback'], rows_twice=_rows_twice(workdir),
             **judge(workdir, [], first_out, ref))
  row['outcome'] = (f"second: exit {second['rc']} in {second['seconds']} s"
                    f"{', one line naming the pid' if refused else ''}; first: {row['outcome']}"
                    f"{'' if not row['rows_twice'] else ', CSV rows twice'}")
  row['ok'] = twin_ok(row)
  shutil.rmtree(workdir, ignore_errors=True)
  return row


def crafted_chunk(module: str, name: str, opcode: str, command: str) -> bytes:
  """A pickle that looks `module`/`name` up and calls it with `command` (what `pickle.dumps`
  never writes, e.g. a dotted name through a module)."""
  def text(s):
    b = s.encode()
    return b'\x8c' + bytes([len(b)]) + b  # SHORT_BINUNICODE.
  if opcode == 'stack':  # Protocol 4: STACK_GLOBAL.
    head = b'\x80\x04' + text(module) + text(name) + b'\x93'
  else:  # Protocol 0's GLOBAL.
    head = b'c' + module.encode() + b'\n' + name.encode() + b'\n'
  return head + text(command) + b'\x85R.'  # TUPLE1, REDUCE, STOP.


def pickle_trial(runner: Runner, index: int, python: str):
  """A crafted chunk file through experiments.train: one line, exit 2, nothing run."""
  module, name, opcode = PAYLOADS[index % len(PAYLOADS)]
  folder = os.path.join(runner.scratch, f'pickle_{index}')
  shutil.rmtree(folder, ignore_errors=True)
  os.makedirs(folder)
  marker, evil = os.path.join(folder, 'ran'), os.path.join(folder, 'chunk_0.pt')
  call = f"touch {marker}" if name != 'eval' else f"open({marker!r}, 'w')"
  with open(evil, 'wb') as f:
    f.write(crafted_chunk(module, name, opcode, call))
  workdir = os.path.join(folder, 'run')
  cmd = [python, '-m', 'experiments.train', '--config=door_open.py:smoke',
         '--config.data.source=tdmpc2', f'--config.data.path={evil}', f'--workdir={workdir}']
  saved, runner.env = runner.env, pickle_environment(runner, python)
  try:
    got = runner.run(cmd, f'pickle_{index}')
  finally:
    runner.env = saved
  line = got['errors'][0] if len(got['errors']) == 1 else ''
  ran = os.path.exists(marker)
  row = dict(kind='offline', fault=f'crafted chunk: {module}.{name} ({opcode})',
             point='data loading', rc=got['rc'], traceback=got['traceback'], errors=got['errors'],
             payload_ran=ran, torch_checked='refused to load' in line, identical=None,
             max_abs_diff=None, final_hash=None, resumed_from=0,
             one_line=len(got['errors']) == 1 and not got['traceback'])
  row['outcome'] = (f"exit {got['rc']}, {'one line' if row['one_line'] else 'NOT one line'}, "
                    f"payload {'RAN' if ran else 'not run'}: {line[:120]}")
  row['ok'] = pickle_ok(row)
  shutil.rmtree(folder, ignore_errors=True)
  return row


def pickle_environment(runner: Runner, python: str) -> Dict[str, str]:
  """The runner's environment, with this checkout and the project's own packages on PYTHONPATH
  (so ahead of `python`'s own) when it is another interpreter (one that has torch): it must be
  the same Python version. A trial whose run never reached the unpickler is not ok
  (`pickle_ok`: `torch_checked`)."""
  if os.path.abspath(python) == os.path.abspath(sys.executable):  # A venv links the same binary.
    return runner.env
  import sysconfig  # pylint: disable=g-import-not-at-top
  extra = [os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
           sysconfig.get_paths()['purelib']]
  return dict(runner.env, PYTHONPATH=os.pathsep.join(extra))


def output_full_trial(runner: Runner, ref: Dict[str, Any], index: int):
  """`evaluate --out` (even index; on the offline reference's workdir) or `collect --out` (odd)
  onto a full tmpfs: exit 1 on one line naming the full disk, nothing left there but what filled
  it."""
  from benchmarks.fault_disk import mount_disk, top_up  # pylint: disable=g-import-not-at-top
  mount = os.path.join(runner.scratch, f'output_full_{index}')
  subprocess.run(['umount', mount], capture_output=True, check=False)
  mount_disk(mount, 256)
  try:
    ballast = os.path.join(mount, 'ballast')
    top_up(ballast, 0)
    if index % 2 == 0:
      what, out = 'evaluate', os.path.join(mount, 'evaluation.json')
      cmd = [sys.executable, '-m', 'experiments.evaluate', f"--workdir={ref['workdir']}",
             '--modes=plan', '--splits=held_out', '--episodes=1', f'--out={out}']
    else:
      what, out = 'collect', os.path.join(mount, 'data.npz')
      cmd = [sys.executable, '-m', 'experiments.collect', '--task=door-open-v3', '--episodes=2',
             f'--out={out}']
    got = runner.run(cmd, f'output_full_{index}')
    left = sorted(set(os.listdir(mount)) - {'ballast'})
  finally:
    subprocess.run(['umount', mount], capture_output=True, check=False)
  line = got['errors'][0] if len(got['errors']) == 1 else ''
  one_line = bool(line) and not got['traceback']
  row = dict(kind='offline', fault=f'{what} --out on a full disk', point='writing the result',
             rc=got['rc'], traceback=got['traceback'], errors=got['errors'], left=left,
             one_line=one_line, identical=None, max_abs_diff=None, final_hash=None,
             resumed_from=0)
  row['outcome'] = (f"exit {got['rc']}, {'one line' if one_line else 'NOT one line'}"
                    f"{', left ' + ', '.join(left) if left else ', nothing left'}: {line[:120]}")
  row['ok'] = output_ok(row)
  return row
