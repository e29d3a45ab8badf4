"""Fault injection (issue 72): SIGKILL offline and online `:smoke` runs at random points, damage
random checkpoint files, and check that every run either resumes to the uninterrupted run's final
parameters or stops on one line with an intact earlier checkpoint.

  python -m benchmarks.fault_injection --kills=20 --damages=10 --disk_full=3 \
      --out=results/faults/faults.json

- References: two uninterrupted runs of each kind, the second keeping every checkpoint: whether
  they end on the same bits, and every step's state, against which the checkpoint a resume
  restores is compared; the second's wall time (compiled, its data collected) sets the range of
  the kill delays.
- Kills (`--kills` per kind): the run is killed with SIGKILL after a delay drawn uniformly over
  3-97% of the reference's wall time (so startup, acting, updates, periodic and final
  evaluation and checkpoint writes are all hit); every fourth kill instead waits a random delay,
  then kills as soon as a checkpoint write is seen in progress (orbax's temporary step folder, or
  an online buffer file without its orbax step). The same command then runs to completion.
- Damage (`--damages`, alternating kinds, alternating a completed workdir, a copy of the
  reference's, and a killed one): one file under <workdir>/checkpoints/<step>/ (the newest step
  60% of the time, else another at random) is deleted or truncated to a random length; then
  `experiments.evaluate` (1 planner episode) and the training command run on the workdir.
- Disk full (`--disk_full` per kind; needs root): the run's workdir on a tmpfs of 20-95% of the
  reference's final workdir size, so that it fills up mid-run; the run must stop on one line
  naming the full disk, its newest checkpoint with the uninterrupted run's bits; then the tmpfs
  grows (space freed) and the same command runs again, judged as a resume.
  `--disk_filled` per kind: the tmpfs is roomy, and another file fills it from a random moment
  on (0-64 KiB left), so that any write can fail; removing that file frees the space.
- Each rerun: exit code, a Python traceback in stderr or not, the warnings naming skipped steps,
  the step it resumed from, and the final TrainState (parameters, EMA parameters, optimizer
  state, step) against the reference's, leaf by leaf, exactly.

Writes one JSON row per trial to --out (rewritten after every trial, so an interrupted session
keeps what it did) and the markdown table beside it (.md); prints a summary line. The runs use
the test suite's compilation settings (tests/conftest.py: a persistent compilation cache, XLA's
optimisations mostly off), one run at a time. Stops starting trials after --max_minutes.
"""

import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from typing import Any, Dict, List, Optional

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TMP_SUFFIX = '.orbax-checkpoint-tmp'
TRACEBACK = 'Traceback (most recent call last)'
_SKIPPED = re.compile(r'checkpoint step (\d+) in \S+ skipped, (.*?); trying an earlier one')
# A progress bar left on the line an error line then continues (tqdm ends it only when closed).
_LEADING_BAR = re.compile(r'^(?:[\w ]+:\s+\d+%\|[^|]*\|\s*\d+/\d+\s*\[[^\]]*\]\s*)+')
_BAR = re.compile(r'(train|online):\s+\d+%\|[^|\r\n]*\|\s*(\d+)/(\d+)')
OFFLINE_STEPS = 12  # Training steps of the offline smoke run; a checkpoint every 2.


def commands(kind: str, workdir: str, scratch: str) -> List[str]:
  """The training command of `kind` ('offline' or 'online') into `workdir`."""
  if kind == 'offline':
    extra = ['--config=door_open.py:smoke', f'--config.data.dir={scratch}/data',
             f'--config.train.num_steps={OFFLINE_STEPS}', '--config.train.checkpoint_every=2']
  else:
    extra = ['--config=door_open_online.py:smoke']  # 120 env steps; a checkpoint every 40.
  return [sys.executable, '-m', 'experiments.train', *extra, f'--workdir={workdir}']


def environment(scratch: str) -> Dict[str, str]:
  """The runs' environment: tests/conftest.py's compilation settings, one cache for all runs."""
  env = dict(os.environ)
  env.setdefault('JAX_COMPILATION_CACHE_DIR', os.path.join(scratch, 'xla_cache'))
  env.setdefault('JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS', '0')
  env.setdefault('JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES', '0')
  env.setdefault('JAX_DISABLE_MOST_OPTIMIZATIONS', '1')
  from importlib import metadata  # pylint: disable=g-import-not-at-top
  if metadata.version('jaxlib').startswith('0.10.') and 'XLA_FLAGS' not in env:
    env['XLA_FLAGS'] = '--xla_cpu_use_fusion_emitters=false'
  return env


# ---------------------------------------------------------------- the workdir, as seen from outside


def complete_steps(workdir: str) -> List[int]:
  """Checkpoint steps whose folder is final (orbax renames its temporary folder when done)."""
  path = os.path.join(workdir, 'checkpoints')
  names = os.listdir(path) if os.path.isdir(path) else []
  return sorted(int(n) for n in names if n.isdigit())


def writing_checkpoint(workdir: str) -> bool:
  """Whether a checkpoint write is in progress: orbax's temporary step folder, or an online
  buffer file whose orbax step is not there yet."""
  path = os.path.join(workdir, 'checkpoints')
  if os.path.isdir(path) and any(TMP_SUFFIX in n for n in os.listdir(path)):
    return True
  buffers = os.path.join(workdir, 'online')
  steps = set(complete_steps(workdir))
  return os.path.isdir(buffers) and any(
      n.startswith('buffer_') and n.endswith('.npz') and int(n[7:-4]) not in steps
      for n in os.listdir(buffers) if n[7:-4].isdigit())


def phase(workdir: str, stderr_text: str, total: int) -> str:
  """What the run was doing when killed, from its workdir and progress bar."""
  if writing_checkpoint(workdir):
    return 'checkpoint write'
  steps = complete_steps(workdir)
  if os.path.exists(os.path.join(workdir, 'report.json')):
    return 'report written'
  if steps and steps[-1] >= total:
    return 'final evaluation'
  bars = _BAR.findall(stderr_text)
  if not bars:
    return 'startup'
  name, done, _ = bars[-1]
  what = 'training' if name == 'train' else 'acting/updates'
  return f'{what} at {done}/{total}'


def checkpoint_files(workdir: str, step: int) -> List[str]:
  """Every file under <workdir>/checkpoints/<step>/, relative to that folder, sorted."""
  root = os.path.join(workdir, 'checkpoints', str(step))
  out = []
  for folder, _, files in os.walk(root):
    out += [os.path.relpath(os.path.join(folder, f), root) for f in files]
  return sorted(out)


def damage(workdir: str, rng: random.Random) -> Dict[str, Any]:
  """Deletes or truncates (to a random length) one random file of one checkpoint step: the
  newest 60% of the time, else another. Returns what was done."""
  steps = complete_steps(workdir)
  if not steps:
    raise ValueError(f'no checkpoint to damage in {workdir}')
  step = steps[-1] if len(steps) == 1 or rng.random() < 0.6 else rng.choice(steps[:-1])
  name = rng.choice(checkpoint_files(workdir, step))
  path = os.path.join(workdir, 'checkpoints', str(step), name)
  size = os.path.getsize(path)
  if rng.random() < 0.5:
    os.remove(path)
    return dict(step=step, file=name, action='delete', size=size, left=None,
                text=f'delete {step}/{name}')
  left = int(rng.random() * size)
  with open(path, 'r+b') as f:
    f.truncate(left)
  return dict(step=step, file=name, action='truncate', size=size, left=left,
              text=f'truncate {step}/{name} to {left} of {size} bytes')


def read_stderr(text: str) -> Dict[str, Any]:
  """From a run's stderr: a traceback or not, the steps skipped (with why), its error lines."""
  lines = [_LEADING_BAR.sub('', l).strip() for l in re.split(r'[\r\n]', text)]
  lines = [l for l in lines if l]
  return dict(traceback=TRACEBACK in text,
              skipped=[int(s) for s, _ in _SKIPPED.findall(text)],
              skip_reasons=[r[:160] for _, r in _SKIPPED.findall(text)],
              errors=[l for l in lines if l.startswith('error:')])


def compare_trees(got, want) -> Dict[str, Any]:
  """Leaf by leaf: identical (same structure, shapes, dtypes and bits) and the largest absolute
  difference of the numeric leaves (inf when the structures differ)."""
  import jax  # pylint: disable=g-import-not-at-top
  a, tree_a = jax.tree_util.tree_flatten(got)
  b, tree_b = jax.tree_util.tree_flatten(want)
  if tree_a != tree_b or len(a) != len(b):
    return dict(identical=False, max_abs_diff=float('inf'))
  a, b = [np.asarray(x) for x in a], [np.asarray(x) for x in b]
  if any(x.shape != y.shape or x.dtype != y.dtype for x, y in zip(a, b)):
    return dict(identical=False, max_abs_diff=float('inf'))
  identical = all(np.array_equal(x, y, equal_nan=x.dtype.kind == 'f') for x, y in zip(a, b))
  diffs = [float(np.max(np.abs(x.astype(np.float64) - y.astype(np.float64))))
           for x, y in zip(a, b) if x.size and x.dtype.kind in 'fiu']
  return dict(identical=identical, max_abs_diff=max(diffs, default=0.0))


def state_hash(state) -> Optional[str]:
  """A short digest of a state's leaves (to group runs that ended on the same bits)."""
  import hashlib  # pylint: disable=g-import-not-at-top
  import jax  # pylint: disable=g-import-not-at-top
  if state is None:
    return None
  digest = hashlib.sha256()
  for leaf in jax.tree_util.tree_leaves(state):
    digest.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
  return digest.hexdigest()[:12]


def step_hashes(workdir: str) -> Dict[int, str]:
  """{step: `state_hash`} of every checkpoint step of an intact workdir."""
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  import orbax.checkpoint as ocp  # pylint: disable=g-import-not-at-top
  config = checkpointing.load_config(workdir)
  manager = checkpointing.checkpoint_manager(workdir)
  target = checkpointing.abstract_state(config)
  return {step: state_hash(manager.restore(step, args=ocp.args.StandardRestore(target)))
          for step in manager.all_steps()}


def final_state(workdir: str):
  """(step, TrainState as numpy) of the workdir's newest intact checkpoint; (None, None) when
  it has none (a warning line per damaged step, as the library prints)."""
  import jax  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  try:
    config = checkpointing.load_config(workdir)
    step, state, _ = checkpointing.restore_intact(checkpointing.checkpoint_manager(workdir),
                                                  config)
  except (checkpointing.WorkdirError, FileNotFoundError):
    return None, None
  return step, (None if state is None else jax.tree.map(np.asarray, state))


# ---------------------------------------------------------------------------------- the runs


class Runner:
  """Starts the runs, one at a time, with stderr kept under <scratch>/logs."""

  def __init__(self, scratch: str, timeout: float):
    self.scratch, self.timeout, self.env = scratch, timeout, environment(scratch)
    os.makedirs(os.path.join(scratch, 'logs'), exist_ok=True)

  def log(self, name: str) -> str:
    return os.path.join(self.scratch, 'logs', name + '.err')

  def start(self, cmd: List[str], name: str) -> subprocess.Popen:
    with open(self.log(name), 'w') as err:  # The child keeps its own descriptor.
      return subprocess.Popen(cmd, cwd=REPO, env=self.env, stdout=subprocess.DEVNULL,
                              stderr=err, start_new_session=True)

  def run(self, cmd: List[str], name: str) -> Dict[str, Any]:
    """Runs `cmd` to its end: exit code, seconds and what its stderr says (`read_stderr`)."""
    start = time.perf_counter()
    proc = self.start(cmd, name)
    try:
      rc = proc.wait(timeout=self.timeout)
    except subprocess.TimeoutExpired:
      os.killpg(proc.pid, signal.SIGKILL)  # The group this runner started.
      rc = proc.wait()
    with open(self.log(name)) as f:
      text = f.read()
    return dict(rc=rc, seconds=round(time.perf_counter() - start, 1), **read_stderr(text))

  def kill_after(self, cmd: List[str], name: str, workdir: str, delay: float, at_write: bool,
                 total: int) -> Dict[str, Any]:
    """Starts `cmd`, SIGKILLs it after `delay` seconds (`at_write`: after `delay`, at the first
    checkpoint write seen) and says when and where it was killed."""
    start = time.perf_counter()
    proc = self.start(cmd, name)
    deadline = start + delay
    while proc.poll() is None and time.perf_counter() < deadline:
      time.sleep(0.02)
    while at_write and proc.poll() is None and not writing_checkpoint(workdir):
      time.sleep(0.003)
    seconds = time.perf_counter() - start
    if proc.poll() is not None:
      return dict(killed=False, kill_s=round(seconds, 2), phase='finished before the kill',
                  steps_at_kill=complete_steps(workdir), first_rc=proc.returncode)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    steps, folder = complete_steps(workdir), os.path.join(workdir, 'checkpoints')
    in_progress = sorted(n for n in os.listdir(folder) if TMP_SUFFIX in n) if os.path.isdir(
        folder) else []
    with open(self.log(name)) as f:
      where = phase(workdir, f.read(), total)
    return dict(killed=True, kill_s=round(seconds, 2), phase=where, steps_at_kill=steps,
                tmp_at_kill=in_progress, first_rc=proc.returncode)

  def evaluate(self, workdir: str, name: str) -> Dict[str, Any]:
    """experiments.evaluate on the workdir (1 planner episode): exit code, traceback, the step
    it loaded."""
    out = os.path.join(self.scratch, 'logs', name + '_eval.json')
    cmd = [sys.executable, '-m', 'experiments.evaluate', f'--workdir={workdir}', '--modes=plan',
           '--splits=held_out', '--episodes=1', f'--out={out}', '--overwrite']
    got = self.run(cmd, name + '_eval')
    step = None
    if got['rc'] == 0 and os.path.exists(out):
      with open(out) as f:
        step = json.load(f)['step']
    return dict(eval_rc=got['rc'], eval_traceback=got['traceback'], eval_update_step=step,
                eval_errors=got['errors'], eval_skipped=got['skipped'])


def restored(workdir: str, ref: Dict[str, Any]) -> Dict[str, Any]:
  """What a resume would restore (the newest intact step, as the library picks it; read only)
  and whether its state has the bits of the uninterrupted run's state at that step."""
  step, state = final_state(workdir)
  return dict(restored_step=step, restored_as_reference=(
      None if step is None else ref['step_hashes'].get(step) == state_hash(state)))


def only_checkpoint_damaged(row: Dict[str, Any]) -> bool:
  """Whether a damage trial hit the workdir's only checkpoint (nothing earlier to fall back to)."""
  return 'damage' in row and row['steps_before_rerun'] == [row['damage']['step']]


def verdict(row: Dict[str, Any]) -> bool:
  """The issue's test: the rerun ends on the uninterrupted run's final state (TrainState bits),
  or stops on one line (no traceback) with an intact earlier checkpoint (or with none when the
  damaged one was the only one); a checkpoint it restored has the uninterrupted run's bits at
  that step, and an evaluation of a damaged workdir loads or stops on one line too."""
  if row.get('restored_as_reference') is False or row.get('eval_ok') is False:
    return False
  if 'disk_kib' in row and not (row['first_rc'] == 0 or row['first_stop_ok']):
    return False
  if row['rc'] == 0:
    return not row['traceback'] and bool(row['identical'])
  return bool(row['one_line']) and (row['intact_step'] is not None
                                    or only_checkpoint_damaged(row))


def judge(workdir: str, before: List[int], rerun: Dict[str, Any],
          ref: Dict[str, Any]) -> Dict[str, Any]:
  """The rerun's outcome against the reference: resumed from which step, its final state
  identical to the uninterrupted run's or not; or stopped, on one line or not, an intact
  checkpoint left."""
  resumed_from = max([s for s in before if s not in rerun['skipped']], default=0)
  row = dict(resumed_from=resumed_from, rc=rerun['rc'], traceback=rerun['traceback'],
             skipped=rerun['skipped'], skip_reasons=rerun['skip_reasons'],
             errors=rerun['errors'], rerun_s=rerun['seconds'])
  step, state = final_state(workdir)
  if rerun['rc'] == 0:
    got = compare_trees(state, ref['state']) if state is not None else dict(
        identical=False, max_abs_diff=float('inf'))
    row.update(final_step=step, **got)
    row['outcome'] = f"resumed from {resumed_from or 'scratch'}"
  else:
    one_line = len(rerun['errors']) == 1 and not rerun['traceback']
    row.update(final_step=None, identical=None, max_abs_diff=None, intact_step=step,
               one_line=one_line)
    row['outcome'] = (f"stopped (exit {rerun['rc']}, {'one line' if one_line else 'NOT one line'}"
                      f"; intact checkpoint: {step if step is not None else 'none'})")
  row['final_hash'] = state_hash(state) if rerun['rc'] == 0 else None
  return row


# ------------------------------------------------------------------------------------ trials


def total_of(kind: str) -> int:
  """The final checkpoint step of `kind`'s run (training steps offline, env steps online)."""
  return OFFLINE_STEPS if kind == 'offline' else 120


def reference(runner: Runner, kind: str) -> Dict[str, Any]:
  """Two uninterrupted runs, the second keeping every checkpoint: the first's workdir and final
  state, the digest of every step's state (from the second, `step_hashes`), whether the two
  ended on the same bits, and the second's wall seconds (compiled and its data collected
  already, as in the trials: the range of the kill delays)."""
  workdir = os.path.join(runner.scratch, f'{kind}_reference')
  shutil.rmtree(workdir, ignore_errors=True)
  got = runner.run(commands(kind, workdir, runner.scratch), f'{kind}_reference')
  if got['rc'] != 0:
    raise RuntimeError(f'the uninterrupted {kind} run failed: see '
                       f'{runner.log(kind + "_reference")}')
  step, state = final_state(workdir)
  again = os.path.join(runner.scratch, f'{kind}_reference_all_steps')
  shutil.rmtree(again, ignore_errors=True)
  second = runner.run(commands(kind, again, runner.scratch) + [
      '--config.train.max_checkpoints=100'], f'{kind}_reference_all_steps')
  if second['rc'] != 0:
    raise RuntimeError(f'the second uninterrupted {kind} run failed: see '
                       f'{runner.log(kind + "_reference_all_steps")}')
  out = dict(kind=kind, workdir=workdir, seconds=got['seconds'], step=step, state=state,
             kib=disk_kib(workdir),
             steps=complete_steps(workdir), hash=state_hash(state), duration=second['seconds'],
             step_hashes=step_hashes(again),
             repeat=dict(seconds=second['seconds'], **compare_trees(final_state(again)[1], state)))
  shutil.rmtree(again, ignore_errors=True)
  return out


def kill_trial(runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random):
  """Kill a fresh run of ref's kind at a random point, run the command again, judge it."""
  kind = ref['kind']
  name = f'{kind}_kill_{index}'
  workdir = os.path.join(runner.scratch, name)
  shutil.rmtree(workdir, ignore_errors=True)
  cmd = commands(kind, workdir, runner.scratch)
  at_write = index % 4 == 3
  delay = rng.uniform(0.03, 0.97) * ref['duration']
  if at_write:
    delay = rng.uniform(0.0, 0.7) * ref['duration']
  killed = runner.kill_after(cmd, name, workdir, delay, at_write, total_of(kind))
  before, kept = complete_steps(workdir), restored(workdir, ref)
  rerun = runner.run(cmd, name + '_rerun')
  row = dict(kind=kind, fault='SIGKILL at a checkpoint write' if at_write else 'SIGKILL',
             delay_s=round(delay, 2), **killed, steps_before_rerun=before, **kept,
             point=f"{killed['kill_s']:.1f} s: {killed['phase']}",
             **judge(workdir, before, rerun, ref))
  row['ok'] = verdict(row)
  shutil.rmtree(workdir, ignore_errors=True)
  return row


def damage_trial(runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random,
                 completed: bool):
  """Damage one checkpoint file of a completed (even `completed`) or killed workdir of ref's
  kind; evaluate it, run the training command again, judge it."""
  kind = ref['kind']
  name = f'{kind}_damage_{index}'
  workdir = os.path.join(runner.scratch, name)
  shutil.rmtree(workdir, ignore_errors=True)
  cmd = commands(kind, workdir, runner.scratch)
  if completed:
    shutil.copytree(ref['workdir'], workdir)
    base = dict(base='completed run', point='after the run')
  else:  # Killed at a random point after its first checkpoint.
    proc = runner.start(cmd, name)
    while proc.poll() is None and not complete_steps(workdir):
      time.sleep(0.02)
    time.sleep(rng.uniform(0.0, 0.4) * ref['duration'])
    if proc.poll() is None:
      os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    base = dict(base='killed run', point=f'killed with steps {complete_steps(workdir)}')
  hurt = damage(workdir, rng)
  before, kept = complete_steps(workdir), restored(workdir, ref)
  evaluated = runner.evaluate(workdir, name)
  rerun = runner.run(cmd, name + '_rerun')
  row = dict(kind=kind, fault=hurt['text'], damage=hurt, **base, steps_before_rerun=before,
             **kept, **evaluated, **judge(workdir, before, rerun, ref))
  row['eval_checkpoint'] = max([s for s in before if s not in evaluated['eval_skipped']],
                              default=None) if evaluated['eval_rc'] == 0 else None
  row['eval_ok'] = (not evaluated['eval_traceback'] and (
      evaluated['eval_rc'] == 0 or len(evaluated['eval_errors']) == 1))
  row['ok'] = verdict(row)
  shutil.rmtree(workdir, ignore_errors=True)
  return row


# ------------------------------------------------------------------------ a disk that fills up


def disk_kib(path: str) -> int:
  """KiB that `path` takes on its disk (du)."""
  return int(subprocess.run(['du', '-sk', path], capture_output=True, text=True,
                            check=True).stdout.split()[0])


# ---------------------------------------------------------------------------------- records


def _cell(row: Dict[str, Any]) -> str:
  if row['identical'] is None:
    return 'n/a (stopped)'
  if row['identical']:
    return 'yes'
  return f"no (max abs diff {row['max_abs_diff']:.2g})"


def markdown(rows: List[Dict[str, Any]]) -> str:
  """The table: trial, kind, fault, point, outcome, final params identical?, traceback?"""
  lines = ['| trial | kind | fault | point | outcome | final params identical? | traceback? |',
           '| --- | --- | --- | --- | --- | --- | --- |']
  for row in rows:
    outcome = row['outcome']
    if row['rc'] == 0 and row.get('restored_step') is not None:
      outcome += (', its checkpoint as uninterrupted' if row['restored_as_reference'] else
                  ", its checkpoint NOT the uninterrupted run's")
    if row.get('skipped'):
      outcome += f" (skipped step {', '.join(map(str, row['skipped']))})"
    if row['rc'] != 0 and only_checkpoint_damaged(row):
      outcome += ', the damaged step being its only checkpoint'
    if 'disk_kib' in row:
      outcome = f"{row['first_outcome']}; after freeing space: {outcome}"
    if 'eval_rc' in row:
      outcome += (f"; evaluate: checkpoint {row['eval_checkpoint']}" if row['eval_rc'] == 0 else
                  f"; evaluate: exit {row['eval_rc']}")
    traceback = ('yes' if row['traceback'] or row.get('eval_traceback')
                 or row.get('first_traceback') or row.get('second_traceback') else 'no')
    lines.append(f"| {row['trial']} | {row['kind']} | {row['fault']} | {row['point']} | "
                 f"{outcome} | {_cell(row)} | {traceback} |")
  return '\n'.join(lines) + '\n'


def group_of(row: Dict[str, Any]) -> str:
  """'kill', 'disk full' (a small disk), 'disk filled' (by another file) or 'damage'."""
  if 'SIGKILL' in row['fault']:
    return 'kill'
  for word, group in (('SIGINT', 'interrupt'), ('second copy', 'twin'), ('crafted', 'pickle'),
                      ('--out on a full disk', 'output disk full')):
    if word in row['fault']:
      return group
  if 'disk_kib' in row:
    return 'disk filled' if 'fill_s' in row else 'disk full'
  return 'damage'


def summary(rows: List[Dict[str, Any]]) -> Dict[str, Any]:
  """Counts per kind of trial, and whether runs resumed from the same step ended alike."""
  out = {}
  for key in sorted({(r['kind'], group_of(r)) for r in rows}):
    group = [r for r in rows if (r['kind'], group_of(r)) == key]
    out[' '.join(key)] = dict(
        trials=len(group), ok=sum(r['ok'] for r in group),
        identical=sum(bool(r['identical']) for r in group),
        stopped_one_line=sum(r['rc'] != 0 and bool(r.get('one_line')) for r in group),
        tracebacks=sum(bool(r['traceback'] or r.get('eval_traceback') or r.get('first_traceback')
                            or r.get('second_traceback')) for r in group),
        checkpoint_not_as_uninterrupted=sum(r.get('restored_as_reference') is False
                                            for r in group),
        resumed_from={str(s): sum(r['resumed_from'] == s and r['rc'] == 0 for r in group)
                      for s in sorted({r['resumed_from'] for r in group})})
    if key[1].startswith('disk'):  # The run on the full disk, before the rerun.
      out[' '.join(key)].update(first_stopped_one_line=sum(r['first_stop_ok'] for r in group),
                                first_finished=sum(r['first_rc'] == 0 for r in group))
  ends = {}
  for r in rows:
    if r['final_hash']:
      ends.setdefault(f"{r['kind']} from {r['resumed_from']}", set()).add(r['final_hash'])
  out['distinct_final_states_per_resume_step'] = {k: len(v) for k, v in sorted(ends.items())}
  return out


def summary_line(rows: List[Dict[str, Any]]) -> str:
  s = summary(rows)
  parts = [f"{k}: {v['ok']}/{v['trials']} ok, " + (
      f"{v['first_stopped_one_line']} stopped on one line naming the full disk and "
      f"{v['first_finished']} finished before the disk filled; after freeing space: "
      if 'first_finished' in v else '') + f"{v['identical']} identical final states, "
           f"{v['stopped_one_line']} stopped on one line, {v['tracebacks']} tracebacks, "
           f"{v['checkpoint_not_as_uninterrupted']} restored a checkpoint unlike the "
           "uninterrupted run's"
           for k, v in s.items() if k != 'distinct_final_states_per_resume_step']
  return '; '.join(parts)


def write(out: str, header: Dict[str, Any], rows: List[Dict[str, Any]]) -> None:
  """The JSON (header, summary and rows) and the markdown table beside it, atomically."""
  os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
  with open(out + '.tmp', 'w') as f:
    json.dump(dict(header, summary=summary(rows), rows=rows), f, indent=1)
  os.replace(out + '.tmp', out)
  table = os.path.splitext(out)[0] + '.md'
  with open(table + '.tmp', 'w') as f:
    f.write(f"{header['command']}\n\n{summary_line(rows)}\n\n{markdown(rows)}")
  os.replace(table + '.tmp', table)


def parse(argv: Optional[List[str]] = None) -> argparse.Namespace:
  p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  p.add_argument('--kills', type=int, default=20, help='SIGKILLs per kind of run')
  p.add_argument('--damages', type=int, default=10, help='damaged checkpoints, kinds alternating')
  p.add_argument('--disk_full', type=int, default=3, help='runs per kind on a small tmpfs that '
                 'fills up (needs root to mount it)')
  p.add_argument('--disk_filled', type=int, default=0, help='runs per kind on a tmpfs that '
                 'another file fills from a random moment on (needs root)')
  p.add_argument('--interrupts', type=int, default=0, help='SIGINTs (Ctrl-C) per kind of run')
  p.add_argument('--twins', type=int, default=0, help='second copies on one workdir, per kind')
  p.add_argument('--pickles', type=int, default=0, help='crafted TD-MPC2 chunk files')
  p.add_argument('--outputs_full', type=int, default=0, help='evaluate/collect --out onto a full '
                 'tmpfs, alternating (needs root and the offline kind)')
  p.add_argument('--pickle_python', default=sys.executable, help='an interpreter with torch and '
                 'tensordict for --pickles (this checkout and its packages go on its path)')
  p.add_argument('--kinds', default='offline,online')
  p.add_argument('--seed', type=int, default=0)
  p.add_argument('--out', default='results/faults/faults.json')
  p.add_argument('--scratch', default='/tmp/faults', help='workdirs, logs, compilation cache')
  p.add_argument('--timeout', type=float, default=600, help='seconds per run')
  p.add_argument('--max_minutes', type=float, default=1e9, help='start no trial after this')
  p.add_argument('--retable', action='store_true', help='run nothing: the verdicts, summary '
                 'and table of the rows already in --out again (after a change to them)')
  return p.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> List[Dict[str, Any]]:
  from benchmarks import fault_disk  # pylint: disable=g-import-not-at-top (it imports this one)
  args = parse(argv)
  if args.retable:
    with open(args.out) as f:
      records = json.load(f)
    from benchmarks.fault_cases import VERDICTS  # pylint: disable=g-import-not-at-top
    rows = [dict(r, ok=VERDICTS.get(group_of(r), verdict)(r)) for r in records.pop('rows')]
    write(args.out, {k: v for k, v in records.items() if k != 'summary'}, rows)
    print(summary_line(rows))
    return rows
  start, rng = time.time(), random.Random(args.seed)
  runner = Runner(os.path.abspath(args.scratch), args.timeout)
  kinds = args.kinds.split(',')
  refs = {k: reference(runner, k) for k in kinds}
  words = sys.argv[1:] if argv is None else argv
  header = dict(command='python -m benchmarks.fault_injection ' + ' '.join(words),
                git_commit=_commit(), environment={k: runner.env[k] for k in sorted(runner.env)
                                                   if k.startswith(('JAX_', 'XLA_'))},
                references={k: {f: v for f, v in r.items() if f not in ('state',)}
                            for k, r in refs.items()})
  plan = [('kill', k, i) for k in kinds for i in range(args.kills)]
  plan += [('damage', kinds[i % len(kinds)], i) for i in range(args.damages)]
  plan += [('disk', k, i) for k in kinds for i in range(args.disk_full)]
  plan += [('filled', k, i) for k in kinds for i in range(args.disk_filled)]
  plan += [(what, k, i) for what, n in (('interrupt', args.interrupts), ('twin', args.twins))
           for k in kinds for i in range(n)]
  plan += [('pickle', 'offline', i) for i in range(args.pickles)]
  plan += [('output', 'offline', i) for i in range(args.outputs_full)]
  rows = []
  for what, kind, i in plan:
    if time.time() - start > 60 * args.max_minutes:
      header['stopped_early'] = f'--max_minutes={args.max_minutes} reached; {len(rows)} trials run'
      break
    if what in ('interrupt', 'twin', 'pickle', 'output'):
      trial = _case(what, runner, refs[kind], i, rng, args.pickle_python)
    elif what == 'kill':
      trial = kill_trial(runner, refs[kind], i, rng)
    elif what == 'disk':
      trial = fault_disk.disk_full_trial(runner, refs[kind], i, rng)
    elif what == 'filled':
      trial = fault_disk.disk_filled_trial(runner, refs[kind], i, rng)
    else:  # Per kind: completed, completed, killed, killed, ...
      trial = damage_trial(runner, refs[kind], i, rng, completed=(i // len(kinds)) % 2 == 0)
    rows.append(dict(trial=len(rows) + 1, **trial))
    print(f"{rows[-1]['trial']:3d} {kind} {rows[-1]['fault']} | {rows[-1]['point']} | "
          f"{rows[-1]['outcome']} | identical: {rows[-1]['identical']}", flush=True)
    header['minutes'] = round((time.time() - start) / 60, 1)
    write(args.out, header, rows)
  header['minutes'] = round((time.time() - start) / 60, 1)
  write(args.out, header, rows)
  print(summary_line(rows))
  return rows


def _case(what: str, runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random,
          python: str) -> Dict[str, Any]:
  """A trial of issue 102's faults (benchmarks/fault_cases.py)."""
  from benchmarks import fault_cases  # pylint: disable=g-import-not-at-top (it imports this one)
  if what == 'pickle':
    return fault_cases.pickle_trial(runner, index, python)
  if what == 'output':
    return fault_cases.output_full_trial(runner, ref, index)
  trial = fault_cases.interrupt_trial if what == 'interrupt' else fault_cases.twin_trial
  return trial(runner, ref, index, rng)


def _commit() -> Optional[str]:
  try:
    return subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=REPO, capture_output=True,
                          text=True, check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return None


if __name__ == '__main__':
  main()
