"""Policies against an anchor policy (the actor prior by default) on the same episodes: pooled
and per-run success with paired tests, where in the episode the planner falls behind, per task;
and their markdown tables (experiments.evaluate selection, experiments.report behind)."""

from typing import Dict, List, Sequence

import numpy as np

from ld_mpc_jax.ops import stats


def departure_share(records: Sequence[dict]) -> float:
  """Decisions that departed from the actor prior's own sequence, over all decisions."""
  return sum(r['departures'] for r in records) / max(sum(r['length'] for r in records), 1)


def against_anchor(records: Sequence[dict], anchor: str = 'actor') -> List[dict]:
  """Per policy: pooled and per-run success, the paired test against `anchor` pooled and per run
  (`most_behind`: the most episodes one run's policy lost to its anchor, net), and for planners
  ('plan...') the share of decisions that departed from the actor prior's own sequence and,
  with the fallback, `fallbacks`: the episodes it handed to the actor prior."""
  policies = list(dict.fromkeys(r['policy'] for r in records))
  runs = list(dict.fromkeys(r['run'] for r in records))
  base = stats.select(records, policy=anchor)
  rows = []
  for policy in policies:
    mine = stats.select(records, policy=policy)
    rates = stats.spread(mine, 'run')['rates']
    row = dict(policy=policy, **stats.summarize(mine), per_run=[rates[str(run)] for run in runs])
    if policy.startswith('plan') and all('departures' in r for r in mine):
      row['departure_share'] = departure_share(mine)
    if policy.startswith('plan') and mine and all('fallback_at' in r for r in mine):
      row['fallbacks'] = sum(r['fallback_at'] is not None for r in mine)
    if base and policy != anchor:
      row['vs_anchor'] = stats.paired(mine, base)
      per_run = [stats.paired(stats.select(mine, run=run), stats.select(base, run=run))
                 for run in runs]
      row['vs_anchor_per_run'] = per_run
      row['most_behind'] = max(m['b_only'] - m['a_only'] for m in per_run)
    rows.append(row)
  return rows


def behind_by_anchor_time(records: Sequence[dict], anchor: str = 'actor',
                          edges: Sequence[int] = (70, 90, 110)) -> List[dict]:
  """Where the policies lose to `anchor`, by how many decisions the anchor took to succeed.

  Pairs each policy's records with the anchor's on the same episodes (stats.episode_key). The
  anchor's solved episodes are binned by its `first_success`: [0, edges[0]), ..., [edges[-1],
  inf); one more row holds the episodes it failed. Returns one dict per bin, in that order:
  `bin` ('lo-hi' decisions, or 'failed'), `episodes` (the anchor's episodes in the bin), and per
  policy `lost` (anchor solved, policy failed) in the solved bins or `won` (policy solved) in the
  failed one, each as [count, paired episodes] (a policy not run on every episode of the anchor
  has fewer).
  """
  edges = list(edges)
  if edges != sorted(set(edges)) or (edges and edges[0] <= 0):
    raise ValueError(f'edges must be increasing positive decision counts, got {edges}')
  base = {stats.episode_key(r): r for r in stats.select(records, policy=anchor)}
  if not base:
    raise ValueError(f'no records of the anchor policy {anchor!r}')
  bounds = [0] + edges + [None]
  names = [f'{lo}-{hi}' if hi else f'{lo}+' for lo, hi in zip(bounds[:-1], bounds[1:])]
  bin_of = lambda r: (names[int(np.searchsorted(edges, r['first_success'], side='right'))]
                      if int(r['success']) else 'failed')
  rows = {name: dict(bin=name, episodes=0) for name in names + ['failed']}
  for r in base.values():
    rows[bin_of(r)]['episodes'] += 1
  policies = [p for p in dict.fromkeys(r['policy'] for r in records) if p != anchor]
  for row in rows.values():
    row['won' if row['bin'] == 'failed' else 'lost'] = {p: [0, 0] for p in policies}
  for r in records:
    a = base.get(stats.episode_key(r))
    if r['policy'] == anchor or a is None:
      continue
    row = rows[bin_of(a)]
    won = row['bin'] == 'failed'
    count = row['won' if won else 'lost'][r['policy']]
    count[0] += int(r['success']) if won else 1 - int(r['success'])
    count[1] += 1
  return list(rows.values())


def behind_markdown(rows: Sequence[dict], anchor: str = 'actor') -> str:
  """A table of `behind_by_anchor_time`: one row per bin, one column per policy."""
  policies = list(rows[0]['lost'])
  lines = [f'| {anchor}: decisions to success | {anchor}: episodes | ' + ' | '.join(policies)
           + ' |', '| --- | --- |' + ' --- |' * len(policies)]
  for row in rows:
    counts = row['won'] if row['bin'] == 'failed' else row['lost']
    verb = 'solved' if row['bin'] == 'failed' else 'lost'
    cells = [f'{verb} {k}/{n}' for k, n in (counts[p] for p in policies)]
    lines.append(f'| {row["bin"]} | {row["episodes"]} | ' + ' | '.join(cells) + ' |')
  return '\n'.join(lines) + '\n'


def against_anchor_by_task(records: Sequence[dict], anchor: str = 'actor') -> Dict[str, List[dict]]:
  """{task: `against_anchor` of that task's records}, in the records' task order; {} when the
  records hold fewer than two tasks (a single-task checkpoint: the pooled rows say it all)."""
  names = list(dict.fromkeys(r.get('task') for r in records))
  if len(names) < 2:
    return {}
  return {name: against_anchor(stats.select(records, task=name), anchor) for name in names}


def by_task_markdown(by_task: Dict[str, List[dict]], anchor: str = 'actor') -> str:
  """One row per task, one column per policy: pooled successes, and for the others the paired
  test against `anchor` (only this / only anchor, exact McNemar p) and the most episodes one
  training seed lost to it."""
  if not by_task:
    return ''
  policies = [r['policy'] for r in next(iter(by_task.values()))]
  lines = ['| task | ' + ' | '.join(policies) + ' |', '| --- ' * (len(policies) + 1) + '|']
  for name, rows in by_task.items():
    cells = []
    for r in rows:
      cell = f"{r['successes']}/{r['episodes']}"
      if 'vs_anchor' in r:
        v = r['vs_anchor']
        cell += f"; {v['a_only']} / {v['b_only']}, p = {v['p_value']:.2g}; behind {r['most_behind']}"
      cells.append(cell)
    lines.append(f'| {name} | ' + ' | '.join(cells) + ' |')
  return (f'Per task (vs {anchor}: only this / only {anchor}, p; most episodes behind {anchor} on '
          'one seed):\n\n' + '\n'.join(lines) + '\n')


def anchor_markdown(rows: Sequence[dict], anchor: str = 'actor') -> str:
  """The rows of `against_anchor` as a markdown table."""
  lines = [f'| policy | held-out success, pooled | per training seed | decisions departing '
           f'from the actor prior | vs {anchor}: only this / only {anchor}, p | per seed | '
           f'most episodes behind {anchor} on one seed |', '| --- ' * 7 + '|']
  for r in rows:
    dep = f"{r['departure_share']:.2f}" if 'departure_share' in r else ''
    if 'fallbacks' in r:  # Episodes the fallback handed to the actor prior.
      dep += f"; fallback in {r['fallbacks']}/{r['episodes']} episodes"
    seeds = ', '.join(f'{x:.2f}' for x in r['per_run'])
    if 'vs_anchor' in r:
      v = r['vs_anchor']
      vs = f"{v['a_only']} / {v['b_only']}, {v['p_value']:.2g}"
      per = ', '.join(f"{m['a_only']} / {m['b_only']}" for m in r['vs_anchor_per_run'])
      behind = str(r['most_behind'])
    else:
      vs = per = behind = ''
    lines.append(f"| {r['policy']} | {r['successes']}/{r['episodes']} = {r['success_rate']:.2f} "
                 f"| {seeds} | {dep} | {vs} | {per} | {behind} |")
  return '\n'.join(lines) + '\n'
