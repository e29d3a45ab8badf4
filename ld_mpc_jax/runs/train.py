"""The training entry, and the main job offline: the task's dataset, updates, then the final
evaluation and report.

`train_and_evaluate(config, workdir)` is the one place in runs/ that reads the config: it checks
it and the workdir, and builds each training seed's `runs.seed_plan.SeedPlan`, which the rest
reads. The run directory, checkpoints, evaluations and report files are `ld_mpc_jax.runs.loop`'s;
with `config.online.enabled` the job is online (`ld_mpc_jax.runs.online`) instead.
"""

import json
import os
import sys
import time
from typing import Any, Dict, Optional, Sequence

import jax
import ml_collections
import numpy as np

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax import data
from ld_mpc_jax.eval import multitask_eval, run_files
from ld_mpc_jax.runs import loop as runs
from ld_mpc_jax.runs.lock import workdir_lock
from ld_mpc_jax.runs.progress import progress_bar, rate_text, stage
from ld_mpc_jax.runs.seed_plan import SeedPlan, check_workdirs
from ld_mpc_jax.ops import sharding
from ld_mpc_jax.runs.checks import checked_plans
from ld_mpc_jax.model.models import count_params
from ld_mpc_jax.learn.train_state import create_train_state, make_update


def train_and_evaluate(config: ml_collections.ConfigDict, workdir: str,
                       continue_with_changes: bool = False) -> Dict[str, Any]:
  """Trains LD-MPC on the task's offline dataset and evaluates it; returns the report.

  Resumes from the latest checkpoint in <workdir>/checkpoints. Writes config.json,
  metrics.csv, eval.csv, tb/ (TensorBoard), losses.png, success.png, episodes.csv (one row per
  evaluation episode), report.json and report.md; a multi-task config (config.tasks) also
  tasks.png, and its report a per-task table ('per_task'). The returned report also holds the
  per-episode records under 'records'.

  The one place in runs/ that reads the config: it checks it and builds each training seed's plan
  (`runs.checks.checked_plans`: the config, the task names, the devices, rendering,
  `online.init_from`), then each seed's workdir against its plan (`seed_plan.check_workdirs`);
  the jobs read the plans.

  A workdir that holds a run of another config is refused (`checkpointing.WorkdirError`, before
  anything is written to it) unless `continue_with_changes`; its earlier config.json is then kept
  as config.<n>.json.

  With `config.online.enabled`, runs the online mode instead (`ld_mpc_jax.runs.online.train_online`);
  with `train.num_seeds` = N > 1, N seeds in one process (`ld_mpc_jax.runs.train_seeds`), each in
  <workdir>/seed<seed>, and the returned report is the pooled one.

  Rerunning a finished run (the same config, its report written) changes nothing: it says so
  on one line and returns the saved report.

  The workdir is locked for the whole run (`ld_mpc_jax.runs.lock.workdir_lock`): a second run on it
  stops at once on one line naming the first one's pid.

  A write that fails for want of space stops the run on one line (`checkpointing.DiskFullError`,
  a WorkdirError) naming the checkpoint the same command resumes from once space is freed.
  """
  with workdir_lock(workdir), checkpointing.stop_when_disk_full(workdir):
    plans = checked_plans(config, workdir)
    finished = finished_report(workdir, plans)
    if finished is not None:  # Rerun of a finished run: nothing is appended or replaced.
      print(f'{workdir} holds this run, finished: nothing to do, nothing changed (to train it '
            'further, raise its step count and pass --continue_with_changes)', file=sys.stderr)
      return finished
    check_workdirs(plans, continue_with_changes)  # Before anything is written.
    os.makedirs(workdir, exist_ok=True)
    if plans[0].online is not None:
      from ld_mpc_jax.runs import online  # pylint: disable=g-import-not-at-top (environments)
      return online.train_online(plans, workdir)
    return _train_offline(plans, workdir)


def finished_report(workdir: str, plans: Sequence[SeedPlan]) -> Optional[Dict[str, Any]]:
  """The report of the run in `workdir` when it has finished as its training seeds' `plans` say
  (runs.checks.checked_plans): each seed's config.json is the one its plan records, no seed's
  checkpoints stop short of its last step (none left at all: deleted after the run, still
  finished), and the report (report.json, or pooled.json for several seeds) is written, last;
  else None."""
  num_seeds = len(plans)
  path = os.path.join(workdir, 'report.json' if num_seeds == 1 else 'pooled.json')
  if not os.path.exists(path):
    return None
  for p in plans:
    end = p.online.env_steps if p.online is not None else p.loop.num_steps
    steps = checkpointing.complete_steps(p.workdir)
    if not os.path.exists(os.path.join(p.workdir, checkpointing.CONFIG_FILE)) or (
        steps and steps[-1] < end):
      return None
    if checkpointing.config_changes(checkpointing.load_config(p.workdir).to_dict(), p.fields()):
      return None  # Another config (refused later) or one continued with changes.
  try:
    with open(path) as f:
      report = json.load(f)
    if num_seeds == 1:  # As a run returns it: with its per-episode records.
      episodes = os.path.join(workdir, 'episodes.csv')
      return dict(report, records=run_files.read_records(episodes)
                  if os.path.exists(episodes) else [])
    return report
  except (OSError, ValueError):
    return None  # A damaged report: the run finishes again and rewrites it.


def _train_offline(plans: Sequence[SeedPlan], workdir: str) -> Dict[str, Any]:
  """The offline job of the training seeds' `plans` (checked, their workdirs too)."""
  first = plans[0]  # The seeds' plans differ in their seeds only.
  # config.data.source: scripted or TD-MPC2 chunks.
  dataset = data.load_dataset(first.data)
  stage(f'data: {dataset.num_episodes:,} episodes, {dataset.num_transitions:,} transitions '
        f'({first.data.source}, {first.task})')
  runs.check_data_fits(dataset, first.learn.model, first.loop.batch_size)
  if not first.loop.data_parallel:  # N >= 1 seeds on the seed axis (runs.train_seeds).
    from ld_mpc_jax.runs import train_seeds  # pylint: disable=g-import-not-at-top
    return train_seeds.train_seeds(plans, workdir, dataset, _report, _summary_md)
  # One seed, its batch split over every device (and process): the data-parallel job.
  run = runs.Run(first)
  state = run.restore()
  if state is None:
    state = create_train_state(first.learn, jax.random.key(first.seed), dataset.observations)
  job = OfflineJob(run, dataset, state)
  t = first.loop
  try:
    runs.loop(run, job, t.num_steps, t.checkpoint_every, t.eval_every)
  finally:
    job.bar.close()  # Its line ends: an error line (a full disk) starts a line of its own.
  run.manager.wait_until_finished()
  state = job.state
  final, baselines, summary, records = run.final_evaluation(
      sharding.unreplicate(state.ema_params), int(state.step))
  report = _report(run, dataset, job, final, baselines, summary, records)
  return run.write_report(report, _summary_md(report), records)


class _Timer:
  """Update steps per second between log points; the first interval (compilation) is not timed."""

  def __init__(self, start_step: int):
    self.steps, self.seconds, self.last_time, self.last_step = 0, 0.0, None, start_step

  def tick(self, step: int) -> None:
    now = time.perf_counter()
    if self.last_time is not None:
      self.steps += step - self.last_step
      self.seconds += now - self.last_time
    self.last_time, self.last_step = now, step

  @property
  def steps_per_s(self) -> float:
    return self.steps / self.seconds if self.seconds else float('nan')


class OfflineJob:
  """Data-parallel offline training of one seed as a `runs.Job` (`train.data_parallel`): each
  advance is one update on dataset windows, the batch split over the devices. Without it,
  offline training is runs.train_seeds.OfflineSeedsJob for any number of seeds."""

  def __init__(self, run: runs.Run, dataset: data.Dataset, state):
    plan = run.plan
    t = self.loop = plan.loop
    self.run, self.progress = run, int(state.step)
    self.start = self.progress  # Resumed at (0 from scratch).
    self.prior_seconds = run.prior_seconds() if self.progress else 0.0
    mesh = sharding.make_mesh() if t.data_parallel else None
    self.update = make_update(plan.learn, mesh)
    self.batch_size, self.put = t.batch_size, lambda batch: batch
    if mesh is not None:  # Each process samples its share; the state lives on every device.
      self.batch_size = sharding.local_batch_size(t.batch_size, mesh)
      self.put = lambda batch: sharding.shard_batch(batch, mesh)
      state = sharding.replicate(state, mesh)
    self.state, self.metrics = state, None
    # A resumed run continues the sampler's stream past the batches of the steps before its
    # checkpoint, so it trains on the windows an uninterrupted run trains on (and ends on its
    # parameters, bit for bit: benchmarks/fault_injection.py). Every process of a
    # multi-process run draws its own windows (process 0 draws what a single-process run draws).
    seed = plan.seed * 1_000_003 + 999_983 * jax.process_index()
    self.buffer = data.make_buffer(dataset, data.window_length(plan.learn.model.horizon),
                                   plan.learn.model.num_tasks, seed=seed)
    self.buffer.skip(self.progress, self.batch_size)
    self.key = jax.random.key(plan.seed + 1)
    self.timer = _Timer(self.progress)
    self.bar = progress_bar(t.num_steps, self.progress, 'train')

  def advance(self) -> None:
    self.state, self.metrics = self.update(self.state, self.put(self.buffer.sample(
        self.batch_size)), jax.random.fold_in(self.key, self.progress))
    self.progress += 1
    self.bar.update(1)

  def log(self, before: int) -> None:
    """metrics.csv and TensorBoard every `train.log_every` steps, at checkpoints and the end."""
    done, t = self.progress, self.loop
    if done % t.log_every and done % t.checkpoint_every and done != t.num_steps:
      return
    self.timer.tick(done)
    metrics = jax.device_get(self.metrics)
    self.run.check_loss(metrics['loss'], f'step {done}')
    self.bar.set_postfix(loss=f"{metrics['loss']:.3f}", steps_s=rate_text(self.timer.steps_per_s))
    row = {'step': done, **{k: float(v) for k, v in sorted(metrics.items())},
           'steps_per_s': self.timer.steps_per_s}
    run_files.append_csv(os.path.join(self.run.workdir, run_files.METRICS_CSV), row)
    self.run.log_scalars('train', {k: v for k, v in row.items() if k != 'step'}, done)

  def checkpoint(self) -> None:
    self.run.save(self.state, self.progress, self.prior_seconds + self.timer.seconds)

  def eval_params(self):
    return sharding.unreplicate(self.state.ema_params)


def _report(run: runs.Run, dataset, job, final, baselines, summary, records):
  plan = run.plan
  trained = plan.tasks
  return {
      'task': plan.task, 'tasks': list(trained.names),
      'per_task': (multitask_eval.per_task(records, trained.names)
                   if trained.multitask and records else None),
      'success_rate': final['success_rate'], 'success_ci95': final['success_ci95'],
      'mean_return': final['mean_return'], 'mean_length': final['mean_length'],
      'decisions_per_s': final['decisions_per_s'],
      'eval_episodes': plan.evals.episodes, 'eval_seeds': list(plan.evals.seeds),
      'baselines': baselines, 'evaluation': summary,
      'train_seconds': job.prior_seconds + job.timer.seconds, 'steps': int(job.state.step),
      'steps_this_run': job.progress - job.start,
      'steps_per_s': job.timer.steps_per_s,
      'num_params': count_params(job.state.ema_params),
      'dataset': {'source': plan.data.source, 'preset': plan.data.preset,
                  'path': plan.data.path, 'episodes': dataset.num_episodes,
                  'transitions': dataset.num_transitions},
      **run.provenance(),
  }


def _summary_md(report: Dict[str, Any]) -> str:
  """report.md of an offline run: steps, speed and size, then the final evaluation."""
  made = report['steps_this_run']
  speed = (f"{report['steps_per_s']:.2f} steps/s without compilation"
           if np.isfinite(report['steps_per_s'])
           else f"{made} update step{'s' if made > 1 else ''} in this run, too few to time "
           'without compilation' if made
           else 'no update steps in this run: resumed at the final step')
  intro = [f"{report['steps']} update steps in {report['train_seconds']:.0f} s of training "
           f"({speed}); {report['num_params']:,} parameters.", '']
  return runs.summary_md(f"LD-MPC on {report['task']}", intro, report, 'EMA parameters; ',
                         'dataset')
