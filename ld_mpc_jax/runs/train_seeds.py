"""The training seeds of an offline run in one process (`train.num_seeds` = N >= 1; one seed is
N = 1 of the same path, written into the workdir itself; `train.data_parallel` runs
train.OfflineJob instead).

With N > 1 each seed is the run it would make alone: its own plan (runs.seed_plan.SeedPlan: seed
config.seed + i, its config saved as a run of one seed), run directory <workdir>/seed<seed>, data
order and update keys; their TrainStates are stacked on a leading seed axis, one stack per device
(`train.seed_devices`, `ops.seed_groups`), and the update is vmapped over each device's seeds
(`train_state.make_seeds_update`; with one seed, the unbatched update on the squeezed stack), one
jitted call per device, dispatched without waiting. Checkpoints, logs, periodic and final
evaluations and reports are each seed's own; N > 1 adds pooled.json and pooled.md.
"""

import json
import os
import time
import types
from typing import Any, Dict, Sequence

import jax
import numpy as np

from ld_mpc_jax import data
from ld_mpc_jax.eval import run_files
from ld_mpc_jax.learn.train_state import create_train_state, make_seeds_update, stack_states
from ld_mpc_jax.ops.seed_groups import SeedGroups
from ld_mpc_jax.runs import loop as runs
from ld_mpc_jax.runs import online_report
from ld_mpc_jax.runs.progress import progress_bar, rate_text
from ld_mpc_jax.runs.seed_plan import SeedPlan


class OfflineSeedsJob:
  """Offline training of N seeds as one `runs.Job`: each advance is one vmapped update."""

  def __init__(self, plans: Sequence[SeedPlan], dataset: data.Dataset):
    """`plans`: each training seed's (runs.seed_plan.seed_plans)."""
    self.plans, self.loop = plans, plans[0].loop
    t = self.loop
    self.seed_runs = [runs.Run(p) for p in plans]
    states = self._restore()
    self.progress = self.start = 0 if states is None else self.seed_runs[0].step
    learn = plans[0].learn  # The seeds' plans differ in their seeds only.
    if states is None:
      states = [create_train_state(learn, jax.random.key(p.seed), dataset.observations)
                for p in plans]
    self.prior_seconds = self.seed_runs[0].prior_seconds() if self.progress else 0.0
    self.groups = SeedGroups(len(plans), t.seed_devices)
    self.states, self.metrics = self.groups.split(stack_states(states)), None
    self.update = {n: make_seeds_update(learn, n) for n in set(self.groups.sizes)}
    self.batch_size = t.batch_size
    # Each seed's sampler as its run alone seeds it (`train.OfflineJob`), continued on resume.
    self.buffers = [data.make_buffer(dataset, data.window_length(p.learn.model.horizon),
                                     learn.model.num_tasks,
                                     seed=p.seed * 1_000_003 + 999_983 * jax.process_index())
                    for p in plans]
    for buffer in self.buffers:
      buffer.skip(self.progress, self.batch_size)
    self.keys = self.groups.split(
        jax.numpy.stack([jax.random.key(p.seed + 1) for p in plans]))
    self._fold = jax.jit(jax.vmap(jax.random.fold_in, in_axes=(0, None)))
    self.seconds, self._last = 0.0, None  # Timed from the second logged interval.
    self._timed_steps = 0
    self.bar = progress_bar(t.num_steps, self.progress,
                            'train' if len(plans) == 1 else f'train x{len(plans)}')

  def _restore(self):
    """Each seed's TrainState at the newest step that every seed has intact, or None."""
    if not any(run.manager.all_steps() for run in self.seed_runs):
      return None
    allowed = set.intersection(*(set(run.manager.all_steps()) for run in self.seed_runs))
    while True:
      reason = lambda step: (None if step in allowed
                             else 'not checkpointed by every seed of this run')
      states = [run.restore(reason) for run in self.seed_runs]
      steps = {run.step for run in self.seed_runs}
      if len(steps) == 1:
        break
      allowed = {s for s in allowed if s <= min(s for s in steps if s is not None)}
    return None if any(s is None for s in states) else states

  def advance(self) -> None:
    batches = [buffer.sample(self.batch_size) for buffer in self.buffers]
    stacked = {k: np.stack([b[k] for b in batches]) for k in batches[0]}
    out = [self.update[n](state, part, self._fold(keys, self.progress)) for n, state, part, keys
           in zip(self.groups.sizes, self.states, self.groups.split_host(stacked), self.keys)]
    self.states, self.metrics = [o[0] for o in out], [o[1] for o in out]
    self.progress += 1
    self.bar.update(1)

  def log(self, before: int) -> None:
    """Each seed's metrics.csv and TensorBoard, as `train.OfflineJob.log` writes them."""
    del before
    done, t = self.progress, self.loop
    if done % t.log_every and done % t.checkpoint_every and done != t.num_steps:
      return
    now = time.perf_counter()
    if self._last is not None:
      self.seconds += now - self._last[0]
      self._timed_steps += done - self._last[1]
    self._last = (now, done)
    rate = self._timed_steps / self.seconds if self.seconds else float('nan')
    metrics = self.groups.join_host(self.metrics)
    for i, run in enumerate(self.seed_runs):
      run.check_loss(metrics['loss'][i], f'step {done} (seed {self.plans[i].seed})')
      row = {'step': done, **{k: float(v[i]) for k, v in sorted(metrics.items())},
             'steps_per_s': rate}
      run_files.append_csv(os.path.join(run.workdir, run_files.METRICS_CSV), row)
      run.log_scalars('train', {k: v for k, v in row.items() if k != 'step'}, done)
    self.bar.set_postfix(loss=f"{float(np.mean(metrics['loss'])):.3f}", steps_s=rate_text(rate))

  def checkpoint(self) -> None:
    for run, state in zip(self.seed_runs, self.groups.per_seed(self.states)):
      run.save(state, self.progress, self.prior_seconds + self.seconds)

  def eval_params(self):
    return self.groups.per_seed([g.ema_params for g in self.states])

  def seed_view(self, i: int) -> types.SimpleNamespace:
    """Seed i as `train._report` reads a job."""
    rate = self._timed_steps / self.seconds if self.seconds else float('nan')
    timer = types.SimpleNamespace(seconds=self.seconds, steps_per_s=rate)
    return types.SimpleNamespace(prior_seconds=self.prior_seconds, timer=timer,
                                 state=self.groups.per_seed(self.states)[i], progress=self.progress,
                                 start=self.start)


def train_seeds(plans: Sequence[SeedPlan], workdir: str, dataset: data.Dataset,
                report_fn, summary_fn) -> Dict[str, Any]:
  """Trains and evaluates every seed of `plans` (runs.seed_plan.seed_plans of the run in
  `workdir`); writes each seed's report and the pooled one."""
  job = OfflineSeedsJob(plans, dataset)
  t = job.loop
  try:
    runs.loop(runs.SeedRuns(job.seed_runs), job, t.num_steps, t.checkpoint_every, t.eval_every)
  finally:
    job.bar.close()  # Its line ends: an error line (an interrupt, a full disk) starts its own.
  reports, records = [], []
  for i, run in enumerate(job.seed_runs):
    run.manager.wait_until_finished()
    params = job.eval_params()[i]
    final, baselines, summary, recs = run.final_evaluation(params, job.progress)
    report = report_fn(run, dataset, job.seed_view(i), final, baselines, summary, recs)
    reports.append(run.write_report(report, summary_fn(report), recs))
    records.append(recs)
  if len(reports) == 1:  # One seed: its run is the workdir, its report the run's.
    return reports[0]
  seeds = [p.seed for p in plans]
  table = online_report.pool_seeds(seeds, records)
  out = dict(task=plans[0].task, steps=job.progress, seeds=seeds, policies=table,
             split=records[0][0]['split'] if records and records[0] else None,
             train_seconds=job.prior_seconds + job.seconds)
  lines = [f"# {out['task']}: {len(seeds)} training seeds in one run, {out['steps']:,} update "
           'steps each', '', f"{out['train_seconds']:.0f} s of training for all seeds together; "
           f"final evaluation on {out['split']} goals, per seed and pooled (Wilson 95% "
           'interval).', '', *online_report.pooled_md(table, seeds), '']
  with open(os.path.join(workdir, online_report.POOLED_JSON), 'w') as f:
    json.dump(out, f, indent=2)
  with open(os.path.join(workdir, online_report.POOLED_MD), 'w') as f:
    f.write('\n'.join(lines))
  return dict(out, seeds=reports)
