"""One run loop for offline and online training: workdir, checkpoints, evaluations, report files.

A run directory holds config.json, checkpoints/ (orbax, with progress.json beside them), tb/
(TensorBoard), eval.csv (periodic held-out evaluations), episodes.csv (the final evaluation's
episodes), the plots (`run_files.write_plots`), report.json and report.md. `Run` writes all of
them, one method per file, for every job; `loop` drives a `Job` (`train_seeds.OfflineSeedsJob`:
one update of every seed per advance, N >= 1 seeds; `train.OfflineJob`: the data-parallel one
seed; `online.job.OnlineJob`: one wave of episodes and its updates) to its end, checkpointing and
evaluating at the same crossings for all.
"""

import json
import os
import time
from typing import Any, Dict, List, Optional, Protocol, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp
from tensorboardX import SummaryWriter
import tqdm

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax import data
from ld_mpc_jax.runs.progress import INTERRUPTED, SAVING, Eta, stage
from ld_mpc_jax.runs.seed_plan import SeedPlan
from ld_mpc_jax.eval import evaluation_suite, multitask_eval, run_files
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.model.settings import ModelSettings

PROGRESS_FILE = 'progress.json'
EVAL_CSV = 'eval.csv'
# Logs with one row per step and the column that holds it (checkpoint steps: training steps
# offline, environment steps online). A resumed run drops their rows past its checkpoint.
STEP_LOGS = ((EVAL_CSV, 'step'), (run_files.METRICS_CSV, 'step'),
             (run_files.ONLINE_CSV, 'env_steps'), (run_files.LOSSES_CSV, 'env_steps'))


def _uncommitted(x):
  """`x` on the default device, uncommitted (a host round trip; a TrainState holds no keys)."""
  if not isinstance(x, jax.Array) or not x.committed:
    return x
  return jnp.asarray(np.asarray(x))


def check_data_fits(dataset: data.Dataset, model: ModelSettings, batch_size: int) -> None:
  """Errors that need the data: windows of H + 1 observations, the batch (config.train's)
  against the dataset's windows, the sizes."""
  longest = int(dataset.episode_lengths.max())
  if model.horizon + 1 > longest:
    raise ValueError(f'config.horizon ({model.horizon}) is too large for the longest episode '
                     f'({longest} transitions): training windows need H + 1 transitions')
  length = data.window_length(model.horizon)
  windows = data.make_buffer(dataset, length, model.num_tasks).num_windows
  if batch_size > windows:
    raise ValueError(f'config.train.batch_size ({batch_size}) is larger than the '
                     f'dataset ({windows} windows of length {length})')
  if dataset.obs_dim != model.obs_dim or dataset.act_dim != model.action_dim:
    raise ValueError(f'config.obs_dim/action_dim ({model.obs_dim}, {model.action_dim}) do not '
                     f'match the dataset ({dataset.obs_dim}, {dataset.act_dim})')


def run_evaluation(spec: EvalSpec, params, mode: str, num_episodes: int, seed: int,
                   obs_noise_std: float = 0.0, video_path: str | None = None,
                   split: str = 'held_out') -> Dict[str, Any]:
  """One policy mode ('plan', 'actor', 'proposal', 'mppi') on one goal split (batched), of the
  evaluation spec of a config (EvalSpec.from_config).

  A multi-task agent: `num_episodes` of every task, pooled (no video).
  """
  if spec.multitask:
    if video_path:
      raise ValueError('no video of a multi-task agent: evaluate one task of it instead')
    return multitask_eval.evaluate_pooled(spec, params, mode, num_episodes, seed, split,
                                          obs_noise_std)
  return evaluation_suite.evaluate_policy(spec, params, mode, num_episodes, seed, split,
                                          obs_noise_std=obs_noise_std, video_path=video_path)


@jax.jit
def _all_finite(tree) -> jax.Array:
  return jax.tree_util.tree_reduce(lambda ok, x: ok & jnp.all(jnp.isfinite(x)), tree,
                                   jnp.array(True))


def save_checkpoint(workdir, manager, state, done, train_seconds) -> None:
  """The TrainState at orbax step `done` (finite parameters only), then progress.json."""
  if not bool(_all_finite(state.params)):  # One host sync per checkpoint.
    raise FloatingPointError(f'non-finite parameters at step {done}; not saved. The last '
                             f'good checkpoint is step {manager.latest_step()}.')
  try:
    manager.save(done, args=ocp.args.StandardSave(state))  # All processes: orbax coordinates.
  except Exception as err:  # pylint: disable=broad-except
    if checkpointing.disk_full(err):  # No partial step left behind; the error goes on.
      checkpointing.remove_partial(manager, done)
    raise
  if not run_files.primary():
    return
  path = os.path.join(workdir, PROGRESS_FILE)
  with open(path + '.tmp', 'w') as f:
    json.dump({'step': done, 'train_seconds': train_seconds}, f)
  os.replace(path + '.tmp', path)


class Run:
  """A run directory: its config.json, checkpoint manager, TensorBoard writer and report files.

  `plan`: the training seed's (runs.seed_plan.seed_plans), whose config.json it records.
  """

  def __init__(self, plan: SeedPlan):
    from ld_mpc_jax.plan.agent import POLICY_MODES  # pylint: disable=g-import-not-at-top
    for mode in plan.evals.baselines:  # Before any training: one line naming the modes.
      POLICY_MODES.check(mode)
    self.plan, self.workdir = plan, plan.workdir
    workdir = plan.workdir
    self.commit = run_files.git_commit()  # The code this process runs: HEAD may move later.
    os.makedirs(workdir, exist_ok=True)
    # Checked first: checkpointing.check_workdir (runs.seed_plan.check_workdirs).
    checkpointing.record_config(plan.config_json, workdir)
    run_files.write_provenance(workdir)  # Commit, dirty flag and command of this start.
    self.manager = checkpointing.checkpoint_manager(workdir, plan.loop.max_checkpoints)
    self.writer = (SummaryWriter(os.path.join(workdir, 'tb')) if run_files.primary()
                   else run_files.NoWriter())

  def provenance(self) -> Dict[str, Any]:
    """The report's closing fields: the config, package versions and the commit."""
    return {'config': self.plan.fields(),
            'versions': run_files.versions(), 'git_commit': self.commit,
            'command': run_files.command_line()}

  def restore(self, usable=None):
    """The newest intact checkpoint's TrainState (its step: `self.step`), or None; the logs lose
    rows written after it (all of them without a checkpoint: a run started over).

    Newer steps that fail to restore, or that `usable(step)` gives a reason against, are skipped
    with a warning and moved to damaged_checkpoints/ (`checkpointing.restore_intact`).
    """
    self.step, state, skipped = checkpointing.restore_intact(
        self.manager, checkpointing.abstract_state(self.plan.learn), usable)
    checkpointing.set_aside(self.workdir, self.manager, skipped)
    if state is not None:
      # Uncommitted, as a fresh state is (orbax restores arrays committed to their device, which
      # lowers to another program): a resumed run then compiles the update a fresh run compiled
      # (one entry in JAX's persistent cache, not two).
      state = jax.tree.map(_uncommitted, state)
    if self.step is not None:
      stage(f'resumed from step {self.step} ({self.workdir})')
    last = -1 if self.step is None else self.step  # From scratch (checkpoints moved aside):
    for name, column in STEP_LOGS:  # every row goes.
      run_files.drop_rows_after(os.path.join(self.workdir, name), column, last)
    return state

  def prior_seconds(self) -> float:
    """Training seconds before the latest checkpoint (progress.json; 0 without one)."""
    path = os.path.join(self.workdir, PROGRESS_FILE)
    if self.manager.latest_step() is None or not os.path.exists(path):
      return 0.0
    with open(path) as f:
      return json.load(f)['train_seconds']

  def save(self, state, step: int, train_seconds: float) -> None:
    save_checkpoint(self.workdir, self.manager, state, step, train_seconds)

  def check_loss(self, loss: float, where: str) -> None:
    """FloatingPointError naming the last good checkpoint when `loss` is not finite."""
    if not np.isfinite(loss):
      raise FloatingPointError(
          f'non-finite loss {loss} at {where}; stopping. The last good checkpoint (step '
          f'{self.manager.latest_step()}) is kept in {self.workdir}/checkpoints.')

  def log_scalars(self, prefix: str, row: Dict[str, Any], step: int) -> None:
    """TensorBoard scalars `prefix/name` of `row`'s finite numbers."""
    for k, v in row.items():
      if isinstance(v, (int, float, np.number)) and np.isfinite(v):
        self.writer.add_scalar(f'{prefix}/{k}', v, step)

  def log_eval(self, step: int, result: Dict[str, Any]) -> None:
    """One eval.csv row, TensorBoard scalars, a progress line and the plots."""
    lo, hi = result['success_ci95']
    run_files.append_csv(os.path.join(self.workdir, EVAL_CSV),
                         {'step': step, 'episodes': result['episodes'],
                          'success_rate': result['success_rate'], 'ci_lo': lo, 'ci_hi': hi,
                          'mean_return': result['mean_return'],
                          'decisions_per_s': result['decisions_per_s']})
    self.writer.add_scalar('eval/success_rate', result['success_rate'], step)
    self.writer.add_scalar('eval/mean_return', result['mean_return'], step)
    tqdm.tqdm.write(f"step {step}: planner success {result['success_rate']:.2f} [{lo:.2f}, "
                    f"{hi:.2f}] over {result['episodes']} episodes on held-out goals")
    run_files.write_plots(self.workdir)

  def periodic_eval(self, params, step: int,
                    missing_since: Optional[int] = None) -> Optional[Dict[str, Any]]:
    """The planner on `eval.periodic_episodes` held-out episodes (none when eval.episodes = 0);
    with `missing_since`, only if eval.csv has no row from that step on (`loop`'s catch-up)."""
    e = self.plan.evals
    if e.episodes <= 0:
      return None
    if missing_since is not None and self.last_eval_step() >= missing_since:
      return None
    stage(f'evaluating at step {step}: the planner on {e.periodic_episodes} held-out episodes')
    result = run_evaluation(self.plan.eval, params, 'plan', e.periodic_episodes, e.seeds[0],
                            split='held_out')
    self.log_eval(step, result)
    return result

  def last_eval_step(self) -> int:
    """The step of eval.csv's last row (-1 without one)."""
    rows = run_files.read_csv(os.path.join(self.workdir, EVAL_CSV))
    return max((int(float(r['step'])) for r in rows), default=-1)

  def final_evaluation(self, params, step: int):
    """Every policy on every goal split and seed: (final, baselines, summary, records).

    `final` and `baselines` are the first split's (held-out goals by default) planner and other
    policies; the records go to episodes.csv.
    """
    e = self.plan.evals
    if e.episodes <= 0:  # eval.episodes = 0: train and checkpoint only.
      final = dict.fromkeys(('success_rate', 'success_ci95', 'mean_return', 'mean_length',
                             'decisions_per_s'))
      return final, {}, {}, []
    modes = ('plan',) + tuple(m for m in e.baselines if m != 'plan')
    splits, evaluate = multitask_eval.grid(self.plan.eval, e.splits)
    stage(f'final evaluation at step {step} ({self.workdir}): {", ".join(modes)} on '
          f'{e.episodes} episode{"s" * (e.episodes != 1)} per goal split '
          f'({", ".join(splits)}) and evaluation seed (seeds {", ".join(map(str, e.seeds))})')
    if splits != e.splits:
      tqdm.tqdm.write(f'goal splits {list(splits)} only: the data were not collected on MT1 '
                      'goals, so there is no train split')
    records = evaluate(self.plan.eval, params, self.workdir, step, modes, splits, e.seeds,
                       e.episodes, run=self.plan.seed, log=tqdm.tqdm.write)
    summary = evaluation_suite.summarize(records)
    if run_files.primary():
      run_files.write_records(os.path.join(self.workdir, 'episodes.csv'), records)
    split = splits[0]
    first = summary[split]['policies']
    final = {**first['plan'], 'split': split}
    self.log_eval(step, final)
    baselines = {m: {**first[m], 'split': split} for m in modes if m != 'plan'}
    return final, baselines, summary, records

  def write_report(self, report: Dict[str, Any], markdown: str, records: List[dict]):
    """report.json, report.md and the plots (tasks.png for a per-task report); returns the
    report with the per-episode records under 'records' (in episodes.csv, not report.json)."""
    self.writer.close()
    run_files.write_plots(self.workdir)
    plots = sorted(n for n in os.listdir(self.workdir) if n.endswith('.png'))
    if plots:
      markdown += '\nPlots: ' + ', '.join(f'[{n}]({n})' for n in plots) + '.\n'
    if run_files.primary():
      with open(os.path.join(self.workdir, 'report.json'), 'w') as f:
        json.dump(report, f, indent=2)
      with open(os.path.join(self.workdir, 'report.md'), 'w') as f:
        f.write(markdown)
    if report.get('per_task') and run_files.primary():
      multitask_eval.plot(os.path.join(self.workdir, 'tasks.png'), report['per_task'],
                          report['tasks'])
    written = sorted(n for n in os.listdir(self.workdir)
                     if os.path.isfile(os.path.join(self.workdir, n)) and not n.startswith('.'))
    stage(f'wrote in {self.workdir}: {", ".join(written)}; checkpoints/, tb/')
    return dict(report, records=records)


class SeedRuns:
  """What `loop` evaluates with when a job trains several seeds: each seed's periodic evaluation
  of its own parameters (`Job.eval_params`, one entry per seed) in its own run directory."""

  def __init__(self, seed_runs: Sequence[Run]):
    self.seed_runs = list(seed_runs)

  def periodic_eval(self, params, step: int, missing_since=None) -> None:
    for run, p in zip(self.seed_runs, params):
      run.periodic_eval(p, step, missing_since)


class Job(Protocol):
  """What `loop` drives: a counter that `advance` moves (update steps or environment steps)."""

  progress: int

  def advance(self) -> None:
    """One unit of work: an update (offline), or a wave of episodes and its updates (online)."""

  def log(self, before: int) -> None:
    """Logs after an advance from `before` to `progress`."""

  def checkpoint(self) -> None:
    """Saves everything a resumed run needs at `progress`."""

  def eval_params(self):
    """The parameters to evaluate (EMA, on one device)."""


def crossed(before: int, after: int, every: int) -> bool:
  """Whether a multiple of `every` lies in (before, after]."""
  return after // every > before // every


def loop(run, job: Job, total: int, checkpoint_every: int, eval_every: int) -> None:
  """Advances `job` until its progress reaches `total`; `run` makes the periodic evaluations
  (a `Run` of the job's one seed, or the `SeedRuns` of its seeds).

  After each advance: `job.log`; a checkpoint when a multiple of `checkpoint_every` is crossed
  and at the end; a periodic evaluation when a multiple of `eval_every` is crossed, except at the
  end (the final evaluation follows). A run resumed from a checkpoint whose periodic evaluation
  never logged (killed during it) makes that evaluation first.
  """
  if job.progress < total:
    stage(f'training from step {job.progress} to {total} (the first step compiles; '
          f'a checkpoint every {checkpoint_every}, an evaluation every {eval_every})')
  due = job.progress // eval_every * eval_every
  if 0 < due and job.progress < total:
    run.periodic_eval(job.eval_params(), job.progress, missing_since=due)
  bar = getattr(job, 'bar', None)
  desc = bar.desc if bar is not None else ''
  eta = Eta(total, eval_every, warm_from=max(job.progress, getattr(job, 'learn_start', 0)))
  while job.progress < total:
    before, start = job.progress, time.perf_counter()
    job.advance()
    if INTERRUPTED.is_set():  # Ctrl-C that a library swallowed: stop here, as it asked.
      raise KeyboardInterrupt
    job.log(before)
    if crossed(before, job.progress, checkpoint_every) or job.progress >= total:
      SAVING.set()
      try:
        job.checkpoint()
      finally:
        SAVING.clear()
      if INTERRUPTED.is_set():
        raise KeyboardInterrupt
    # The rate counts the step with its logging and checkpoint writes (a run checkpointing every
    # few steps spends most of its time there); the evaluations are counted apart.
    eta.advanced(job.progress, time.perf_counter() - start)
    if crossed(before, job.progress, eval_every) and job.progress < total:
      start = time.perf_counter()
      run.periodic_eval(job.eval_params(), job.progress)
      eta.evaluated(time.perf_counter() - start)
    if bar is not None:
      bar.set_description_str(f'{desc} ({eta.text(job.progress)})', refresh=False)


def summary_md(title: str, intro: Sequence[str], report: Dict[str, Any], lead: str,
               trained_on: str) -> str:
  """report.md: `title`, the `intro` lines, the final evaluation's tables and the commit."""
  lines = [f'# {title}', '', *intro]
  return '\n'.join(lines + evaluation_md_lines(report, lead, trained_on)) + '\n'


def evaluation_md_lines(report: Dict[str, Any], lead: str, trained_on: str) -> List[str]:
  """report.md's final-evaluation paragraph and tables, and its commit line (a list of lines).

  `lead` starts the paragraph; held-out goals are those no `trained_on` episode starts from.
  """
  if report['evaluation']:
    lines = [f"{lead}{report['eval_episodes']} episodes per policy, goal split and "
             f"evaluation seed (seeds {', '.join(map(str, report['eval_seeds']))}); the same "
             f'episodes for every policy. Held-out goals: configurations no {trained_on} episode '
             'starts from.', '']
    if report.get('per_task'):
      lines += [f"Per task ({len(report['tasks'])} tasks, one agent; average: mean of the task "
                'rates, interval of all episodes pooled), then all tasks pooled.', '',
                multitask_eval.markdown(report['per_task'], report['tasks']),
                '![success per task](tasks.png)', '']
    lines.append(evaluation_suite.markdown(report['evaluation']))
  else:
    lines = ['Not evaluated (eval.episodes = 0).']
  command = f"; command: `{report['command']}`" if report.get('command') else ''
  return lines + ['', f"git commit {report['git_commit']}{command}."]



