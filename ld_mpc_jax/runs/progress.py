"""What a run tells its user while it works, and how it stops when asked: stage lines, the progress
bar and its ETA, and the interrupt flags the launcher's SIGINT handler sets."""

import sys
import threading

import numpy as np
import tqdm

from ld_mpc_jax.eval import run_files
from ld_mpc_jax.learn.checkpointing import kept_checkpoint


# Set by the launchers' --quiet: no stage lines (`stage`).
QUIET = threading.Event()


def stage(message: str) -> None:
  """One line on stderr saying what the run does now (its data, compiling, evaluating at step N,
  resumed from step N, what it wrote), above any progress bar; none under --quiet, and only from
  the process that writes the run's files."""
  if not QUIET.is_set() and run_files.primary():
    tqdm.tqdm.write(message, file=sys.stderr)


def rate_text(steps_per_s: float) -> str:
  """The bar's steps/s: 'timing' until a second log point gives a rate (the first interval
  holds the compilation and is not timed)."""
  return f'{steps_per_s:.2f}' if np.isfinite(steps_per_s) else 'timing'


def progress_bar(total: int, initial: int, desc: str, unit: str = 'step') -> tqdm.tqdm:
  """A run's progress bar without tqdm's own rate and ETA (its first interval holds the
  compilation, and it knows nothing of evaluations): `loop` writes one ETA into the
  description, `Eta`."""
  return tqdm.tqdm(total=total, initial=initial, desc=desc, unit=unit, dynamic_ncols=True,
                   bar_format='{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]')


class Eta:
  """Time left of a run: the steps left at the rate measured after the first advance past
  `warm_from` (that one compiles; an online run's random seed waves before it are not its rate),
  checkpoint writes in and evaluations out, plus the periodic evaluations left at the measured
  time of one (and the final evaluation, counted as one more); '+ evaluations' until one is timed
  (a run with `eval.episodes = 0` times its empty ones at about 0 s)."""

  def __init__(self, total: int, eval_every: int, warm_from: int = 0):
    self.total, self.eval_every, self.warm_from = total, eval_every, warm_from
    self.start_progress, self.train_s, self.eval_s = None, 0.0, []

  def advanced(self, after: int, seconds: float) -> None:
    if after <= self.warm_from:  # Seed waves: another rate than the run's.
      return
    if self.start_progress is None:  # The first advance compiles: not a rate.
      self.start_progress = after
      return
    self.train_s += seconds

  def evaluated(self, seconds: float) -> None:
    self.eval_s.append(seconds)

  def text(self, progress: int) -> str:
    done = progress - (self.start_progress if self.start_progress is not None else progress)
    if done <= 0 or self.train_s <= 0:
      return 'eta: after the first steps'
    left = (self.total - progress) * self.train_s / done
    if not self.eval_s:
      return f'eta {_minutes(left)} + evaluations'
    evals = (self.total - 1) // self.eval_every - progress // self.eval_every + 1  # + the final.
    return f'eta {_minutes(left + evals * float(np.median(self.eval_s)))}'


def _minutes(seconds: float) -> str:
  return f'{seconds / 60:.0f} min' if seconds < 5400 else f'{seconds / 3600:.1f} h'


# Set by the launcher's SIGINT handler (experiments.train): `loop` stops after the step it is in.
INTERRUPTED = threading.Event()
# Set while a checkpoint is written: the handler then only sets INTERRUPTED, and `loop` stops
# once the checkpoint is complete (a save cut in half would leave orbax's threads failing).
SAVING = threading.Event()


def interrupted_message(workdir: str) -> str:
  """The one line of an interrupted run (Ctrl-C): what is kept and how to resume."""
  step, shown = kept_checkpoint(workdir)
  if step is None:
    return 'interrupted before the first checkpoint; the same command starts the run again'
  return (f'interrupted: checkpoint step {step} is kept in {shown}; the same command resumes '
          'from it')


def quiet_unraisable(hook):
  """`sys.unraisablehook` that drops the KeyboardInterrupt our SIGINT handler raised inside a
  callback that cannot raise (e.g. JAX's gc callback; the flag still stops the run) and passes
  anything else to `hook`."""
  def unraisable(args):
    if not isinstance(args.exc_value, KeyboardInterrupt):
      hook(args)
  return unraisable
