"""Evaluating a multi-task agent: every task with the single-task evaluation, then per task.

Task k is evaluated as a single-task agent: its spec (`EvalSpec.tasks`: `EvalSpec.for_task`, that
of a config of task k alone) with `tasks.bind(params, k)` through `evaluation_suite` (batched
episodes, held-out and train goals of that task's data, cached cells under <workdir>/evals/).
Records gain a `task` field, so policies still pair on the same episodes. `per_task` tabulates
success per task, split and policy with Wilson intervals, and the average over tasks; `markdown`
and `plot` render it.
"""

import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.ops import stats
from ld_mpc_jax.model import tasks


def evaluate_tasks(spec: EvalSpec, params, workdir, step: int,
                   modes: Sequence[str], splits: Sequence[str], seeds: Sequence[int],
                   num_episodes: int, run: Any = None, obs_noise_std: float = 0.0,
                   log=print, only: Optional[Sequence[str]] = None) -> List[dict]:
  """`evaluation_suite.evaluate_checkpoint` for every task (or the tasks named in `only`);
  records carry `task` (its name)."""
  names = [name for name, _ in spec.tasks]
  unknown = [n for n in (only or ()) if n not in names]
  if unknown:
    raise ValueError(f'task {unknown[0]!r} is not one of this checkpoint\'s tasks {list(names)}')
  records = []
  for k, (name, task_spec) in enumerate(spec.tasks):
    if only and name not in only:
      continue
    recs = evaluation_suite.evaluate_checkpoint(
        task_spec, tasks.bind(params, k), workdir, step, modes, splits, seeds,
        num_episodes, run=run, obs_noise_std=obs_noise_std,
        log=lambda line, name=name: log(f'{name}: {line}'))
    for r in recs:
      r['task'] = name
    records.extend(recs)
  return records


def grid(spec: EvalSpec, splits: Sequence[str]) -> Tuple[Tuple[str, ...], Callable]:
  """(the goal splits `spec` can use, the grid evaluation for it).

  The function is `evaluate_tasks` for a multi-task spec (scripted data: both splits), else
  `evaluation_suite.evaluate_checkpoint` (no train split for TD-MPC2's data).
  """
  if spec.multitask:
    return tuple(splits), evaluate_tasks
  return (evaluation_suite.available_splits(spec.goals, splits),
          evaluation_suite.evaluate_checkpoint)


def evaluate_pooled(spec: EvalSpec, params, mode: str, num_episodes: int,
                    seed: int, split: str = 'held_out',
                    obs_noise_std: float = 0.0) -> Dict[str, Any]:
  """One policy on `num_episodes` episodes of every task, pooled (periodic evaluations).

  Returns `stats.summarize` of all records plus the median decisions/s over tasks.
  """
  records = evaluate_tasks(spec, params, None, 0, (mode,), (split,), (seed,), num_episodes,
                           log=lambda line: None, obs_noise_std=obs_noise_std)
  out = stats.summarize(records)
  out['decisions_per_s'] = float(np.median([r['decisions_per_s'] for r in records]))
  return out


def per_task(records: Sequence[dict], names: Sequence[str]) -> Dict[str, Any]:
  """{split: {mode: {'tasks': {name: summary}, 'average': summary}}} of the records.

  A task's summary is `stats.summarize` (successes, rate, Wilson interval, means). 'average' is
  the mean of the task rates, with the Wilson interval of all episodes pooled (the same rate
  when every task has the same number of episodes, as here), and the tasks' rates' spread.
  """
  out: Dict[str, Any] = {}
  for split in dict.fromkeys(r['split'] for r in records):
    out[split] = {}
    for mode in dict.fromkeys(r['policy'] for r in records if r['split'] == split):
      mine = stats.select(records, split=split, policy=mode)
      by_task = {n: stats.summarize(stats.select(mine, task=n)) for n in names
                 if stats.select(mine, task=n)}
      pooled = stats.summarize(mine)
      rates = [s['success_rate'] for s in by_task.values()]
      average = dict(success_rate=float(np.mean(rates)), success_ci95=pooled['success_ci95'],
                     successes=pooled['successes'], episodes=pooled['episodes'],
                     task_rate_std=float(np.std(rates, ddof=1)) if len(rates) > 1 else None)
      out[split][mode] = dict(tasks=by_task, average=average)
  return out


def _cell(s: Dict[str, Any]) -> str:
  lo, hi = s['success_ci95']
  return f"{s['successes']}/{s['episodes']} = {s['success_rate']:.2f} [{lo:.2f}, {hi:.2f}]"


def markdown(table: Dict[str, Any], names: Sequence[str]) -> str:
  """One table per goal split: a row per task, a column per policy, then the average."""
  lines = []
  for split, by_mode in table.items():
    modes = list(by_mode)
    lines += [f'**{split} goals**: success, 95% Wilson interval', '',
              '| task | ' + ' | '.join(evaluation_suite.POLICY_NAMES.get(m, m) for m in modes)
              + ' |', '| --- |' + ' --- |' * len(modes)]
    for name in names:
      if all(name in by_mode[m]['tasks'] for m in modes):
        lines.append(f'| {name} | ' + ' | '.join(_cell(by_mode[m]['tasks'][name])
                                                  for m in modes) + ' |')
    lines.append('| **average** | ' + ' | '.join(
        f"**{by_mode[m]['average']['success_rate']:.2f}** "
        f"[{by_mode[m]['average']['success_ci95'][0]:.2f}, "
        f"{by_mode[m]['average']['success_ci95'][1]:.2f}]" for m in modes) + ' |')
    lines.append('')
  return '\n'.join(lines)


def plot(path: str, table: Dict[str, Any], names: Sequence[str]) -> str:
  """Bar plot of success per task and policy (Wilson intervals as error bars), a panel per split."""
  import matplotlib  # pylint: disable=g-import-not-at-top
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt  # pylint: disable=g-import-not-at-top
  labels = list(names) + ['average']
  fig, axes = plt.subplots(len(table), 1, figsize=(11, 3.6 * len(table)), squeeze=False)
  for ax, (split, by_mode) in zip(axes[:, 0], table.items()):
    width = 0.8 / len(by_mode)
    for j, (mode, s) in enumerate(by_mode.items()):
      cells = [s['tasks'].get(n) for n in names] + [s['average']]
      rate = np.array([c['success_rate'] if c else np.nan for c in cells])
      lo = np.array([c['success_ci95'][0] if c else np.nan for c in cells])
      hi = np.array([c['success_ci95'][1] if c else np.nan for c in cells])
      x = np.arange(len(labels)) + (j - (len(by_mode) - 1) / 2) * width
      ax.bar(x, rate, width, label=evaluation_suite.POLICY_NAMES.get(mode, mode),
             yerr=np.stack([rate - lo, hi - rate]), capsize=2)
    ax.set_xticks(np.arange(len(labels)))
    ax.set_xticklabels([n.removesuffix('-v3') for n in labels], rotation=30, ha='right')
    ax.set_ylabel('success rate'); ax.set_ylim(0, 1.05)
    ax.set_title(f'{split} goals (95% Wilson intervals)'); ax.legend(fontsize=8)
  fig.tight_layout()
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  fig.savefig(path, dpi=100)
  plt.close(fig)
  return path
