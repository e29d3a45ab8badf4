"""Files of a run directory: CSV logs, plots, the TensorBoard writer, provenance.

Only process 0 of a multi-process run writes them (`primary`).
"""

import csv
import json
import os
import subprocess
from importlib import metadata as importlib_metadata
from typing import Any, Dict

import jax
import numpy as np

from ld_mpc_jax import envs

METRICS_CSV = 'metrics.csv'  # An offline run's losses, every `train.log_every` update steps.
ONLINE_CSV = 'online.csv'  # One row per wave of an online run (ld_mpc_jax.runs.online).
LOSSES_CSV = 'losses.csv'  # An online run's losses, the last update of each wave.


def versions() -> Dict[str, str]:
  """Versions of the packages a result depends on, and the device kind."""
  out = {}
  for name in ('jax', 'jaxlib', 'flax', 'optax', 'orbax-checkpoint', *envs.SUITE.packages,
               'numpy'):
    try:
      out[name] = importlib_metadata.version(name)
    except importlib_metadata.PackageNotFoundError:
      out[name] = None
  out['device'] = str(jax.devices()[0].device_kind)
  return out


def git_commit() -> str | None:
  """The checkout's HEAD commit, or None outside a git checkout."""
  try:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=root, capture_output=True,
                          text=True, check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return None


PROVENANCE = 'provenance.jsonl'


def git_dirty() -> bool | None:
  """Whether the checkout has uncommitted changes to tracked files (None outside a checkout)."""
  try:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run(['git', 'status', '--porcelain', '--untracked-files=no'], cwd=root,
                         capture_output=True, text=True, check=True).stdout
    return bool(out.strip())
  except (OSError, subprocess.CalledProcessError):
    return None


def command_line(argv: list | None = None) -> str:
  """This process's command line as one would type it (`python -m experiments.train ...`): as
  given to Python (`sys.orig_argv`; the launchers rewrite sys.argv), or `argv` (sys.argv's form)."""
  import shlex  # pylint: disable=g-import-not-at-top
  import sys  # pylint: disable=g-import-not-at-top
  if argv is None and getattr(sys, 'orig_argv', None):
    return ' '.join(shlex.quote(a) for a in ['python', *sys.orig_argv[1:]])
  argv = list(sys.argv if argv is None else argv)
  root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
  prog = os.path.abspath(argv[0]) if argv else ''
  if prog.endswith('.py') and prog.startswith(root + os.sep):  # python -m experiments.train
    argv[:1] = ['-m', os.path.relpath(prog, root)[:-3].replace(os.sep, '.')]
  return ' '.join(shlex.quote(a) for a in ['python', *argv])


def write_provenance(workdir: str, argv: list | None = None) -> dict:
  """Appends one line to <workdir>/provenance.jsonl at each start of a run (resumes included):
  the time, the commit of the code this process runs, whether the checkout was dirty, the
  command line and the folder it ran in. Returns the entry."""
  import datetime  # pylint: disable=g-import-not-at-top
  entry = dict(started=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'),
               commit=git_commit(), dirty=git_dirty(), command=command_line(argv),
               cwd=os.getcwd())
  if primary():
    with open(os.path.join(workdir, PROVENANCE), 'a') as f:
      f.write(json.dumps(entry) + '\n')
  return entry


def primary() -> bool:
  """Whether this process writes the run's logs and report (process 0 of a multi-process run).

  Every process trains and evaluates alike; checkpoints are saved by all of them together.
  """
  return jax.process_index() == 0


class NoWriter:
  """SummaryWriter stand-in for processes other than 0."""

  def add_scalar(self, *args, **kwargs):
    pass

  def close(self):
    pass


def append_csv(path: str, row: Dict[str, Any]) -> None:
  """Appends `row` to the CSV at `path`, writing its header first if the file is new."""
  if not primary():
    return
  new = not os.path.exists(path)
  with open(path, 'a', newline='') as f:
    writer = csv.DictWriter(f, fieldnames=list(row))
    if new:
      writer.writeheader()
    writer.writerow(row)


def drop_rows_after(path: str, column: str, step: int) -> None:
  """Removes the rows of the CSV at `path` whose `column` is past `step` (replaced atomically).

  A killed run logged them after its last checkpoint; resumed from that checkpoint, it logs
  them again, so keeping them would repeat steps and bend the curves back on themselves.
  """
  if not primary():
    return
  rows = read_csv(path)
  kept = [r for r in rows if float(r[column]) <= step]
  if len(kept) == len(rows):
    return
  with open(path + '.tmp', 'w', newline='') as f:
    writer = csv.DictWriter(f, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(kept)
  os.replace(path + '.tmp', path)


def read_csv(path: str):
  """Rows of the CSV at `path` as dicts of strings; [] if it does not exist."""
  if not os.path.exists(path):
    return []
  with open(path) as f:
    return list(csv.DictReader(f))


RECORD_INTS = ('run', 'eval_seed', 'episode', 'reset_seed', 'success', 'first_success',
               'length', 'env_steps')
RECORD_FLOATS = ('return',)


def read_records(path: str) -> list:
  """The per-episode records of an episodes.csv (`write_records`; gzip-compressed when it ends
  in .gz), with their numeric fields as numbers."""
  import gzip  # pylint: disable=g-import-not-at-top
  with (gzip.open(path, 'rt', newline='') if path.endswith('.gz') else open(path, newline='')
        ) as f:
    rows = list(csv.DictReader(f))
  for r in rows:
    r.update({k: int(r[k]) for k in RECORD_INTS if r.get(k) not in (None, '')})
    r.update({k: float(r[k]) for k in RECORD_FLOATS if r.get(k) not in (None, '')})
  return rows


def write_records(path: str, records) -> None:
  """Per-episode records to the CSV at `path` (episodes.csv), replaced atomically."""
  task = ['task'] if records and 'task' in records[0] else []  # Multi-task agents' records.
  fields = ['run'] + task + ['policy', 'split', 'eval_seed', 'episode', 'reset_seed', 'goal_id',
                             'success', 'first_success', 'return', 'length', 'env_steps']
  with open(path + '.tmp', 'w', newline='') as f:
    writer = csv.DictWriter(f, fieldnames=fields, extrasaction='ignore')
    writer.writeheader()
    writer.writerows(records)
  os.replace(path + '.tmp', path)


def _pyplot():
  import matplotlib  # pylint: disable=g-import-not-at-top
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt  # pylint: disable=g-import-not-at-top
  return plt


def write_plots(workdir: str) -> None:
  """Every plot whose CSV exists: losses.png (metrics.csv), success.png (eval.csv) and, for an
  online run, online.png (online.csv, eval.csv and losses.csv)."""
  if not primary():
    return
  plt = _pyplot()
  rows = read_csv(os.path.join(workdir, METRICS_CSV))
  if rows:
    fig, ax = plt.subplots(figsize=(7, 4))
    steps = [int(r['step']) for r in rows]
    for name in rows[0]:
      if name.startswith('loss'):
        ax.plot(steps, [float(r[name]) for r in rows], label=name)
    ax.set_xlabel('update step'); ax.set_ylabel('loss'); ax.set_yscale('log'); ax.legend()
    fig.tight_layout(); fig.savefig(os.path.join(workdir, 'losses.png'), dpi=100)
    plt.close(fig)
  rows = read_csv(os.path.join(workdir, 'eval.csv'))
  # Online runs (ld_mpc_jax.runs.online writes online.csv) evaluate at environment steps.
  x_label = ('environment step' if os.path.exists(os.path.join(workdir, ONLINE_CSV))
             else 'update step')
  if rows:
    fig, ax = plt.subplots(figsize=(7, 4))
    steps = np.array([int(r['step']) for r in rows])
    rate = np.array([float(r['success_rate']) for r in rows])
    lo, hi = np.array([float(r['ci_lo']) for r in rows]), np.array([float(r['ci_hi']) for r in rows])
    ax.plot(steps, rate, 'o-', label='planner, held-out goals (EMA params)')
    ax.fill_between(steps, lo, hi, alpha=0.2, label='95% Wilson interval')
    ax.set_xlabel(x_label); ax.set_ylabel('success rate'); ax.set_ylim(-0.02, 1.02)
    ax.legend(); fig.tight_layout(); fig.savefig(os.path.join(workdir, 'success.png'), dpi=100)
    plt.close(fig)
  _write_online_plot(workdir)


def _write_online_plot(workdir: str) -> None:
  """online.png: success and return against environment steps (training episodes and held-out
  evaluations), and the loss."""
  waves = read_csv(os.path.join(workdir, ONLINE_CSV))
  if not waves:
    return
  plt = _pyplot()
  evals = read_csv(os.path.join(workdir, 'eval.csv'))
  col = lambda rows, name: np.array([float(r[name]) for r in rows])
  x, ex = col(waves, 'env_steps'), col(evals, 'step')
  fig, axes = plt.subplots(1, 3, figsize=(15, 4))
  axes[0].plot(x, col(waves, 'episode_success'), '.-', alpha=0.6,
               label='training episodes (exploration noise)')
  if evals:
    axes[0].plot(ex, col(evals, 'success_rate'), 'o-', label='planner, held-out goals')
    axes[0].fill_between(ex, col(evals, 'ci_lo'), col(evals, 'ci_hi'), alpha=0.2)
    axes[1].plot(ex, col(evals, 'mean_return'), 'o-', label='planner, held-out goals')
  axes[0].set_ylabel('success rate'); axes[0].set_ylim(-0.02, 1.02)
  axes[1].plot(x, col(waves, 'episode_return'), '.-', alpha=0.6, label='training episodes')
  axes[1].set_ylabel('episode return')
  losses = read_csv(os.path.join(workdir, LOSSES_CSV))
  if losses:
    axes[2].plot(col(losses, 'env_steps'), col(losses, 'loss'), '.-')
    axes[2].set_yscale('log')
  axes[2].set_ylabel('loss (last update of each wave)')
  for ax in axes:
    ax.set_xlabel('environment step')
  axes[0].legend(); axes[1].legend()
  fig.tight_layout(); fig.savefig(os.path.join(workdir, 'online.png'), dpi=100)
  plt.close(fig)
