"""The trial machinery of the fault injection (benchmarks/fault_injection.py, the command): the runs'
commands and environment, a Runner that starts, kills and reruns them, the checkpoints' state, the
faults (SIGKILL, damaged files) and the verdict of a trial against the uninterrupted reference.
benchmarks/fault_cases.py and fault_disk.py build their trials from it."""

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
  from ld_mpc_jax.learn.train_state import LearnSettings  # pylint: disable=g-import-not-at-top
  import orbax.checkpoint as ocp  # pylint: disable=g-import-not-at-top
  config = checkpointing.load_config(workdir)
  manager = checkpointing.checkpoint_manager(workdir)
  target = checkpointing.abstract_state(LearnSettings.from_config(config))
  return {step: state_hash(manager.restore(step, args=ocp.args.StandardRestore(target)))
          for step in manager.all_steps()}


def final_state(workdir: str):
  """(step, TrainState as numpy) of the workdir's newest intact checkpoint; (None, None) when
  it has none (a warning line per damaged step, as the library prints)."""
  import jax  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.learn.train_state import LearnSettings  # pylint: disable=g-import-not-at-top
  try:
    learn = LearnSettings.from_config(checkpointing.load_config(workdir))
    step, state, _ = checkpointing.restore_intact(checkpointing.checkpoint_manager(workdir),
                                                  checkpointing.abstract_state(learn))
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
