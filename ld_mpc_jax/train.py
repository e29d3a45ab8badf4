"""The main job: data, training, checkpoints, evaluation, metrics, plots and a report."""

import json
import os
import time
from typing import Any, Dict

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import orbax.checkpoint as ocp
from tensorboardX import SummaryWriter
import tqdm

from ld_mpc_jax import (checkpointing, data, evaluation_suite, multitask_eval, run_files,
                        sharding, tasks)
from ld_mpc_jax.config_checks import online_enabled, validate_config
from ld_mpc_jax.models import count_params
from ld_mpc_jax.train_state import create_train_state, make_update

PROGRESS_FILE = 'progress.json'


def window_length(config: ml_collections.ConfigDict) -> int:
  """Observations per training window: T = H + 1, plus one for the value bootstrap."""
  return config.horizon + 2


def check_config_for_data(config: ml_collections.ConfigDict, dataset: data.Dataset) -> None:
  """Errors that need the data: windows of H + 1 observations, batch vs. dataset size."""
  longest = int(dataset.episode_lengths.max())
  if config.horizon + 1 > longest:
    raise ValueError(f'config.horizon ({config.horizon}) is too large for the longest episode '
                     f'({longest} transitions): training windows need H + 1 transitions')
  windows = data.make_buffer(config, dataset, window_length(config)).num_windows
  if config.train.batch_size > windows:
    raise ValueError(f'config.train.batch_size ({config.train.batch_size}) is larger than the '
                     f'dataset ({windows} windows of length {window_length(config)})')
  if dataset.obs_dim != config.obs_dim or dataset.act_dim != config.action_dim:
    raise ValueError(f'config.obs_dim/action_dim ({config.obs_dim}, {config.action_dim}) do not '
                     f'match the dataset ({dataset.obs_dim}, {dataset.act_dim})')


def run_evaluation(config, params, mode: str, num_episodes: int, seed: int,
                   obs_noise_std: float = 0.0, video_path: str | None = None,
                   split: str = 'held_out') -> Dict[str, Any]:
  """One policy mode ('plan', 'actor', 'proposal', 'mppi') on one goal split (batched).

  A multi-task agent: `num_episodes` of every task, pooled (no video).
  """
  if tasks.is_multitask(config):
    if video_path:
      raise ValueError('no video of a multi-task agent: evaluate one task of it instead')
    return multitask_eval.evaluate_pooled(config, params, mode, num_episodes, seed, split,
                                          obs_noise_std)
  return evaluation_suite.evaluate_policy(config, params, mode, num_episodes, seed, split,
                                          obs_noise_std=obs_noise_std, video_path=video_path)


def _summary_md(report: Dict[str, Any]) -> str:
  speed = (f"{report['steps_per_s']:.2f} steps/s without compilation"
           if np.isfinite(report['steps_per_s'])
           else 'no update steps in this run: resumed at the final step')
  lines = [f"# LD-MPC on {report['task']}", '',
           f"{report['steps']} update steps in {report['train_seconds']:.0f} s of training "
           f"({speed}); {report['num_params']:,} parameters.", '']
  return '\n'.join(lines + evaluation_md_lines(report, 'EMA parameters; ', 'dataset')) + '\n'


def evaluation_md_lines(report: Dict[str, Any], lead: str, trained_on: str):
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
  return lines + ['', f"git commit {report['git_commit']}."]


def train_and_evaluate(config: ml_collections.ConfigDict, workdir: str) -> Dict[str, Any]:
  """Trains LD-MPC on the task's offline dataset and evaluates it; returns the report.

  Resumes from the latest checkpoint in <workdir>/checkpoints. Writes config.json,
  metrics.csv, eval.csv, tb/ (TensorBoard), losses.png, success.png, episodes.csv (one row per
  evaluation episode), report.json and report.md; a multi-task config (config.tasks) also
  tasks.png, and its report a per-task table ('per_task'). The returned report also holds the
  per-episode records under 'records'.

  With `config.online.enabled`, runs the online mode instead (`ld_mpc_jax.online.train_online`).
  """
  if online_enabled(config):
    from ld_mpc_jax import online  # pylint: disable=g-import-not-at-top (it imports this module)
    return online.train_online(config, workdir)
  commit = run_files.git_commit()  # The code this process runs: HEAD may move while it trains.
  dataset, manager, state, prior_seconds = _prepare(config, workdir)
  writer = (SummaryWriter(os.path.join(workdir, 'tb')) if run_files.primary()
            else run_files.NoWriter())
  state, timer = _train(config, workdir, dataset, manager, state, prior_seconds, writer)
  evaluated = final_evaluation(config, sharding.unreplicate(state.ema_params), int(state.step),
                               workdir, writer)
  writer.close()
  final, baselines, summary, records = evaluated
  report = _report(config, dataset, state, prior_seconds, timer, final, baselines, summary,
                   commit, records)
  if run_files.primary():
    with open(os.path.join(workdir, 'report.json'), 'w') as f:
      json.dump(report, f, indent=2)
    with open(os.path.join(workdir, 'report.md'), 'w') as f:
      f.write(_summary_md(report))
  run_files.write_plots(workdir)
  if report['per_task'] and run_files.primary():
    multitask_eval.plot(os.path.join(workdir, 'tasks.png'), report['per_task'], report['tasks'])
  report['records'] = records  # Per-episode records: in episodes.csv, not report.json.
  return report


def _prepare(config, workdir):
  """Checks the config, loads (or collects) the data, restores the latest checkpoint."""
  validate_config(config)
  tasks.check_tasks(config)
  os.makedirs(workdir, exist_ok=True)
  dataset = data.load_for_config(config)  # config.data.source: scripted or TD-MPC2 chunks.
  check_config_for_data(config, dataset)
  checkpointing.save_config(config, workdir)
  manager = checkpointing.checkpoint_manager(workdir, config.train.max_checkpoints)
  state = checkpointing.restore_latest(manager, config)
  if state is None:
    state = create_train_state(config, jax.random.key(config.seed), dataset.observations)
  prior_seconds = 0.0
  progress_path = os.path.join(workdir, PROGRESS_FILE)
  if int(state.step) and os.path.exists(progress_path):
    with open(progress_path) as f:
      prior_seconds = json.load(f).get('train_seconds', 0.0)
  return dataset, manager, state, prior_seconds


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


def _train(config, workdir, dataset, manager, state, prior_seconds, writer):
  """The update loop from the restored step: logs, checkpoints, periodic evaluations."""
  t_cfg, start = config.train, int(state.step)
  num_steps = t_cfg.num_steps
  mesh = sharding.make_mesh() if t_cfg.get('data_parallel', False) else None
  update = make_update(config, mesh)
  batch_size, put = t_cfg.batch_size, lambda batch: batch
  if mesh is not None:  # Each process samples its share; the state lives on every device.
    batch_size = sharding.local_batch_size(t_cfg.batch_size, mesh)
    put = lambda batch: sharding.shard_batch(batch, mesh)
    state = sharding.replicate(state, mesh)
  # A resumed run draws fresh windows rather than replaying the first run's; so does every
  # process of a multi-process run (process 0 draws what a single-process run draws).
  buffer = data.make_buffer(config, dataset, window_length(config), seed=(
      config.seed * 1_000_003 + start + 999_983 * jax.process_index()))
  train_key = jax.random.key(config.seed + 1)
  timer = _Timer(start)
  bar = tqdm.tqdm(range(start, num_steps), initial=start, total=num_steps, desc='train',
                  dynamic_ncols=True)
  for step in bar:
    state, metrics = update(state, put(buffer.sample(batch_size)),
                            jax.random.fold_in(train_key, step))
    done = step + 1
    if done % t_cfg.log_every == 0 or done % t_cfg.checkpoint_every == 0 or done == num_steps:
      _log_metrics(workdir, writer, bar, timer, done, num_steps, jax.device_get(metrics),
                   manager)
    if done % t_cfg.checkpoint_every == 0 or done == num_steps:
      save_checkpoint(workdir, manager, state, done, prior_seconds + timer.seconds)
    if config.eval.episodes > 0 and done % t_cfg.eval_every == 0 and done != num_steps:
      periodic_eval(config, sharding.unreplicate(state.ema_params), done, workdir, writer)
  bar.close()
  manager.wait_until_finished()
  return state, timer


def _log_metrics(workdir, writer, bar, timer, done, num_steps, metrics, manager) -> None:
  timer.tick(done)
  if not np.isfinite(metrics['loss']):
    raise FloatingPointError(
        f'non-finite loss {metrics["loss"]} at step {done}; stopping. The last good '
        f'checkpoint (step {manager.latest_step()}) is kept in {workdir}/checkpoints.')
  eta = (num_steps - done) / timer.steps_per_s if timer.seconds else float('nan')
  bar.set_postfix(loss=f"{metrics['loss']:.3f}", steps_s=f'{timer.steps_per_s:.2f}',
                  eta_min=f'{eta / 60:.1f}')
  row = {'step': done, **{k: float(v) for k, v in sorted(metrics.items())},
         'steps_per_s': timer.steps_per_s}
  run_files.append_csv(os.path.join(workdir, 'metrics.csv'), row)
  for k, v in row.items():
    if k != 'step' and np.isfinite(v):  # steps/s is NaN until the second log.
      writer.add_scalar(f'train/{k}', v, done)


@jax.jit
def _all_finite(tree) -> jax.Array:
  return jax.tree_util.tree_reduce(lambda ok, x: ok & jnp.all(jnp.isfinite(x)), tree,
                                   jnp.array(True))


def save_checkpoint(workdir, manager, state, done, train_seconds) -> None:
  if not bool(_all_finite(state.params)):  # One host sync per checkpoint.
    raise FloatingPointError(f'non-finite parameters at step {done}; not saved. The last '
                             f'good checkpoint is step {manager.latest_step()}.')
  manager.save(done, args=ocp.args.StandardSave(state))  # All processes: orbax coordinates.
  if not run_files.primary():
    return
  path = os.path.join(workdir, PROGRESS_FILE)
  with open(path + '.tmp', 'w') as f:
    json.dump({'step': done, 'train_seconds': train_seconds}, f)
  os.replace(path + '.tmp', path)


def final_evaluation(config, params, step, workdir, writer):
  """Every policy on every goal split and evaluation seed: (final, baselines, summary, records).

  `final` and `baselines` are the first split's (held-out goals by default) planner and other
  policies.
  """
  if config.eval.episodes <= 0:  # eval.episodes = 0: train and checkpoint only.
    final = dict.fromkeys(('success_rate', 'success_ci95', 'mean_return', 'mean_length',
                           'decisions_per_s'))
    return final, {}, {}, []
  modes = ('plan',) + tuple(m for m in config.eval.get('baselines', ()) if m != 'plan')
  splits, evaluate = multitask_eval.grid(config, config.eval.splits)
  if splits != tuple(config.eval.splits):
    tqdm.tqdm.write(f'goal splits {list(splits)} only: the data were not collected on MT1 '
                    'goals, so there is no train split')
  records = evaluate(config, params, workdir, step, modes, splits, config.eval.seeds,
                     config.eval.episodes, run=config.seed, log=tqdm.tqdm.write)
  summary = evaluation_suite.summarize(records)
  if run_files.primary():
    run_files.write_records(os.path.join(workdir, 'episodes.csv'), records)
  split = splits[0]
  first = summary[split]['policies']
  final = {**first['plan'], 'split': split}
  _log_eval(workdir, writer, step, final)
  baselines = {m: {**first[m], 'split': split} for m in modes if m != 'plan'}
  return final, baselines, summary, records


def _report(config, dataset, state, prior_seconds, timer, final, baselines, summary, commit,
            records):
  names = tasks.task_names(config)
  return {
      'task': config.task, 'tasks': list(names),
      'per_task': (multitask_eval.per_task(records, names)
                   if tasks.is_multitask(config) and records else None),
      'success_rate': final['success_rate'], 'success_ci95': final['success_ci95'],
      'mean_return': final['mean_return'], 'mean_length': final['mean_length'],
      'decisions_per_s': final['decisions_per_s'],
      'eval_episodes': config.eval.episodes, 'eval_seeds': list(config.eval.seeds),
      'baselines': baselines, 'evaluation': summary,
      'train_seconds': prior_seconds + timer.seconds, 'steps': int(state.step),
      'steps_per_s': timer.steps_per_s,
      'num_params': count_params(state.ema_params),
      'dataset': {'source': data.sources.source(config), 'preset': config.data.preset,
                  'path': config.data.get('path'), 'episodes': dataset.num_episodes,
                  'transitions': dataset.num_transitions},
      'config': json.loads(config.to_json_best_effort()),
      'versions': run_files.versions(), 'git_commit': commit,
  }


def _log_eval(workdir, writer, step, result) -> None:
  lo, hi = result['success_ci95']
  run_files.append_csv(os.path.join(workdir, 'eval.csv'),
              {'step': step, 'episodes': result['episodes'],
               'success_rate': result['success_rate'], 'ci_lo': lo, 'ci_hi': hi,
               'mean_return': result['mean_return'],
               'decisions_per_s': result['decisions_per_s']})
  writer.add_scalar('eval/success_rate', result['success_rate'], step)
  writer.add_scalar('eval/mean_return', result['mean_return'], step)
  tqdm.tqdm.write(f"step {step}: planner success {result['success_rate']:.2f} [{lo:.2f}, "
                  f"{hi:.2f}] over {result['episodes']} episodes on held-out goals")
  run_files.write_plots(workdir)


def periodic_eval(config, params, step, workdir, writer):
  result = run_evaluation(config, params, 'plan', config.eval.periodic_episodes,
                          config.eval.seeds[0], split='held_out')
  _log_eval(workdir, writer, step, result)
  return result
