"""The report files of an online run (ld_mpc_jax.runs.online): each training seed's online.csv and
losses.csv (a row per wave) with report.json and report.md, and the pooled table of a run of
several seeds (`train.num_seeds`)."""

import json
import os
from typing import Any, Dict, List, Optional

import numpy as np

from ld_mpc_jax.eval import run_files
from ld_mpc_jax.runs import loop as runs
from ld_mpc_jax.ops import stats
from ld_mpc_jax.model.models import count_params
from ld_mpc_jax.eval.run_files import LOSSES_CSV, ONLINE_CSV
from ld_mpc_jax.plan.search import CANDIDATES


def report(job, seat, final, summary) -> Dict[str, Any]:
  """report.json of one training seed (`seat`, an online.Seat) of `job` (an online.job.OnlineJob)."""
  plan, c, workdir, buffer = seat.run.plan, job.counters, seat.run.workdir, seat.buffer
  curve = [dict(env_steps=int(r['step']), episodes=int(r['episodes']),
                success_rate=float(r['success_rate']), ci95=[float(r['ci_lo']), float(r['ci_hi'])],
                mean_return=float(r['mean_return']))
           for r in run_files.read_csv(os.path.join(workdir, runs.EVAL_CSV))]
  return {
      'task': plan.task, 'mode': 'fine-tune' if job.fine_tune else 'from scratch',
      'init_from': plan.online.init_from or None,
      'env_steps': c['env_steps'], 'updates': c['updates'], 'episodes': c['episodes'],
      'train_seconds': c['train_seconds'], 'seeds_in_run': len(job.seats),
      'env_steps_per_s': c['env_steps'] / c['train_seconds'],
      'success_rate': final['success_rate'], 'success_ci95': final['success_ci95'],
      'mean_return': final['mean_return'], 'eval_episodes': plan.evals.episodes,
      'eval_seeds': list(plan.evals.seeds), 'evaluation': summary, 'curve': curve,
      'num_params': count_params(job.eval_params()[seat.index]),
      'demos': len(buffer.demos), 'reward': plan.online.reward,
      'first_training_success': _first_success(workdir),
      'acting': acting_summary(workdir, plan.online.eval_every),
      'buffer': {'online_episodes': len(buffer.episodes),
                 'offline_episodes': (buffer.offline.num_episodes
                                      if buffer.offline is not None else 0)},
      **seat.run.provenance(),
  }


def log_wave(job, seat, before: int, wave, mode: str, seconds: float) -> None:
  """A wave of one training seed (`seat`, an online.Seat; `wave`, its online.seats.WaveRecord;
  `before`: environment steps before it): a row of online.csv, the wave's last update's losses in
  losses.csv, both in TensorBoard."""
  metrics = {k: float(v[seat.index]) for k, v in sorted(job.learner.seed_metrics().items())}
  step, episodes, c = job.counters['env_steps'], wave.episodes, job.counters
  if metrics:
    seat.run.check_loss(metrics['loss'], f'environment step {step}')
  # Shares of planned decisions: NaN where nothing was planned (random waves, the actor acting).
  decisions = int(wave.winners[:-1].sum()) or float('nan')
  row = dict(env_steps=step, episodes=c['episodes'], updates=c['updates'],
             acting={'plan': 'planner', 'actor': 'actor', 'random': 'random'}[mode],
             episode_return=float(np.mean([e['reward'].sum() for e in episodes])),
             episode_success=float(np.mean([e['success'].any() for e in episodes])),
             max_step_reward=wave.dense_max,  # Dense reward, also under a sparse one.
             **{f'won_{k}': float(wave.winners[j] / decisions)
                for j, k in enumerate(CANDIDATES.names())},
             departed=float(wave.winners[-1] / decisions),
             exec_noise=job.acting_schedule.executed_noise(before)
             if mode != 'random' else float('nan'),
             env_steps_per_s=(step - before) / seconds,
             **_acting_columns(job, seat, before, wave, mode))
  run_files.append_csv(os.path.join(seat.run.workdir, ONLINE_CSV), row)
  if metrics:  # Losses of the wave's last update, from the first update on.
    run_files.append_csv(os.path.join(seat.run.workdir, LOSSES_CSV),
                         dict(env_steps=step, **metrics))
  for k, v in list(row.items())[1:] + [(f'loss/{k}', v) for k, v in metrics.items()]:
    if k != 'acting' and np.isfinite(v):  # NaN marks "not measured" in the CSV only.
      seat.run.writer.add_scalar(f'online/{k}', v, step)


def _acting_columns(job, seat, before: int, wave, mode: str) -> dict:
  """The wave's planned decisions, the mean spread of their candidates' first actions (of the
  first round's, and of the proposal's alone), the intrinsic term's scheduled weights and the
  proposal's mean share of the first round's elites; NaN where nothing was planned. (Last in the row: a run resumed from code without them keeps its
  earlier columns in place.)"""
  spreads = np.asarray(wave.spreads, np.float64).reshape(-1, 2)
  mean = lambda x: float(np.mean(x[x >= 0])) if (x >= 0).any() else float('nan')
  pessimism, disagreement = (job.acting_schedule.exploration(before)
                             if mode == 'plan' else (float('nan'),) * 2)
  out = dict(planned=int(wave.winners[:-1].sum()), spread_first=mean(spreads[:, 0]),
             spread_proposal=mean(spreads[:, 1]), act_pessimism=pessimism,
             act_disagreement=disagreement)
  if seat.novelty:  # Only runs with the exploration value have the column.
    out['act_novelty'] = job.acting_schedule.novelty(before) if mode == 'plan' else float('nan')
  out['elites_proposal'] = mean(wave.elites)  # float64 [D], WaveRecord's.
  return out


POOLED_MD, POOLED_JSON = 'pooled.md', 'pooled.json'


def pool_seeds(seeds: List[int], records: List[List[dict]]) -> Dict[str, Any]:
  """{policy: successes per training seed and pooled (Wilson 95% interval), McNemar against the
  planner on the same episodes} on the first goal split of each seed's final evaluation."""
  policies, first = {}, {}
  for seed, recs in zip(seeds, records):
    split = recs[0]['split'] if recs else None
    for r in recs:
      if r['split'] == split:
        policies.setdefault(r['policy'], {}).setdefault(seed, []).append(int(r['success']))
        first.setdefault(r['policy'], []).append(r)
  table = {m: {'per_seed': {str(s): [sum(v), len(v)] for s, v in per.items()},
               'successes': sum(map(sum, per.values())),
               'episodes': sum(map(len, per.values()))} for m, per in policies.items()}
  for mode, row in table.items():
    row['ci95'] = stats.wilson_interval(row['successes'], row['episodes'])
    # Exact McNemar against the planner on the same episodes (records name their seed: 'run').
    row['vs_plan'] = (stats.paired(first['plan'], first[mode])
                      if mode != 'plan' and 'plan' in first else None)
  return table


def pooled_md(table: Dict[str, Any], seeds: List[int]) -> List[str]:
  """The markdown lines of `pool_seeds`' table."""
  lines = ['| policy | ' + ' | '.join(f'seed {s}' for s in seeds)
           + ' | pooled | 95% CI | planner only / this only, McNemar p |',
           '| --- |' + ' --- |' * (len(seeds) + 3)]
  for mode, row in table.items():
    cells = [f"{row['per_seed'][str(s)][0]}/{row['per_seed'][str(s)][1]}"
             if str(s) in row['per_seed'] else '-' for s in seeds]
    vs = row['vs_plan']
    paired = f"{vs['a_only']} / {vs['b_only']}, p = {vs['p_value']:.2g}" if vs else ''
    lines.append(f"| {mode} | {' | '.join(cells)} | {row['successes']}/{row['episodes']} | "
                 f"[{row['ci95'][0]:.2f}, {row['ci95'][1]:.2f}] | {paired} |")
  return lines


def write_pooled(workdir: str, seeds: List[int], reports: List[Dict[str, Any]],
                 records: List[List[dict]]) -> Dict[str, Any]:
  """pooled.json and pooled.md in `workdir`: each policy's successes per training seed and
  pooled over them (Wilson 95% interval), on the first goal split of the final evaluation."""
  table = pool_seeds(seeds, records)
  out = dict(task=reports[0]['task'], env_steps=reports[0]['env_steps'], seeds=seeds,
             split=records[0][0]['split'] if records and records[0] else None,
             first_training_success={str(s): r['first_training_success']
                                     for s, r in zip(seeds, reports)},
             train_seconds=reports[0]['train_seconds'], policies=table,
             acting={str(s): r['acting']['whole'] for s, r in zip(seeds, reports)})
  lines = [f"# {out['task']}: {len(seeds)} training seeds in one run, "
           f"{out['env_steps']:,} environment steps (simulator steps)", '',
           f"{out['train_seconds']:.0f} s acting and training for all seeds together; final "
           f"evaluation on {out['split']} goals, per seed and pooled (Wilson 95% interval).", '',
           *pooled_md(table, seeds)]
  first = ', '.join(f'seed {s}: {v:,}' if v is not None else f'seed {s}: none'
                    for s, v in zip(seeds, out['first_training_success'].values()))
  lines += ['', f'First successful training episode (environment steps): {first}.', '']
  table = acting_table([(f'seed {s}', part) for s, part in zip(seeds, out['acting'].values())],
                       'training seed')
  lines += [ACTING_INTRO + ' Whole run, per seed:', '', *table, ''] if table else []
  with open(os.path.join(workdir, POOLED_JSON), 'w') as f:
    json.dump(out, f, indent=2)
  with open(os.path.join(workdir, POOLED_MD), 'w') as f:
    f.write('\n'.join(lines))
  return out


def _weighted(rows: List[dict], column: str) -> Optional[float]:
  """The mean of a per-wave share or mean over the waves' planned decisions (None: none)."""
  pairs = [(float(r[column]), int(r['planned'])) for r in rows
           if r.get(column) not in (None, '') and int(r['planned'])]
  pairs = [(v, n) for v, n in pairs if v == v]  # Columns without a value are NaN.
  total = sum(n for _, n in pairs)
  return sum(v * n for v, n in pairs) / total if total else None


def acting_summary(workdir: str, every: int) -> Dict[str, Any]:
  """How the planner acted, from the run's online.csv (`acting_rows_summary`)."""
  return acting_rows_summary(run_files.read_csv(os.path.join(workdir, ONLINE_CSV)), every)


def acting_rows_summary(rows: List[Dict[str, str]], every: int) -> Dict[str, Any]:
  """How the planner acted, from online.csv's `rows`: the share of planned decisions won by each
  kind of candidate (`won_<kind>`) and that departed from the actor prior, the mean spread of
  the candidates' first actions (of the first round's, and of the proposal's) and the proposal's
  share of the first round's elites (`elites_proposal`, where recorded), over the whole run
  and per `every` environment steps (the held-out evaluations' spacing), weighted by each wave's
  planned decisions. Waves logged before online.csv had a `planned` column are left out."""
  rows = [r for r in rows if r.get('planned') not in (None, '')]
  columns = [k for k in (rows[0] if rows else {})
             if k.startswith('won_') or k in ('departed', 'spread_first', 'spread_proposal',
                                                'elites_proposal')]
  def summary(part, env_steps):
    return dict(env_steps=env_steps, planned=sum(int(r['planned']) for r in part),
                **{k: _weighted(part, k) for k in columns})
  spans = {}
  for r in rows:
    spans.setdefault(-(-int(r['env_steps']) // every), []).append(r)
  return dict(whole=summary(rows, int(rows[-1]['env_steps']) if rows else 0),
              spans=[summary(part, int(part[-1]['env_steps']))
                     for _, part in sorted(spans.items())])


ACTING_INTRO = ("While acting (training waves, with exploration): the share of planned decisions "
                "won by each kind of candidate, that departed from the actor prior's own sequence, "
                "the spread of the candidates' first actions (std over candidates, mean over "
                "action dimensions; the first round's, the proposal's), and the proposal's share "
                "of the first round's best `plan.num_elites`, which the refinement rounds start "
                "from (`elites_proposal`).")


def acting_table(rows: List[tuple], first: str) -> List[str]:
  """A markdown table of `acting_summary` parts: rows of (label, summary); [] without a planned
  decision."""
  rows = [(label, part) for label, part in rows if part['planned']]
  if not rows:
    return []
  names = [k for k in rows[0][1] if k not in ('env_steps', 'planned')]
  show = lambda v, k: '-' if v is None else f'{v:.3f}' if k.startswith('spread') else f'{v:.0%}'
  lines = [f"| {first} | planned decisions | {' | '.join(names)} |",
           '| --- | --- |' + ' --- |' * len(names)]
  return lines + [f"| {label} | {part['planned']:,} | "
                  + ' | '.join(show(part[k], k) for k in names) + ' |' for label, part in rows]


def acting_md(acting: Dict[str, Any]) -> List[str]:
  """report.md's paragraph on `acting_summary`, per span and over the whole run."""
  table = acting_table([(f"to {r['env_steps']:,}", r) for r in acting['spans']]
                       + [('whole run', acting['whole'])], 'environment steps')
  return [ACTING_INTRO, '', *table, ''] if table else []


def _first_success(workdir: str) -> Optional[int]:
  """Environment steps (simulator steps) at the end of the first wave with a successful
  training episode (None: none succeeded), from online.csv."""
  for row in run_files.read_csv(os.path.join(workdir, ONLINE_CSV)):
    if float(row['episode_success']) > 0:
      return int(row['env_steps'])
  return None


def summary_md(report: Dict[str, Any]) -> str:
  """report.md: what ran, the held-out curve against environment steps, the final evaluation."""
  start = (f"fine-tuned from `{report['init_from']}` (its dataset and "
           f"{report['buffer']['online_episodes']} online episodes in the buffer)"
           if report['init_from'] else f"from scratch ({report['buffer']['online_episodes']} "
           'online episodes, seed episodes of random actions first)' if not report['demos']
           else f"from scratch with {report['demos']} demonstrations "
           f"({report['buffer']['online_episodes']} online episodes)")
  first = report['first_training_success']
  start += (f"; first successful training episode by {first:,} environment steps"
            if first is not None else '; no training episode succeeded')
  lines = [f"{report['env_steps']:,} environment steps, {report['updates']:,} updates, {start}; "
           f"{report['train_seconds']:.0f} s acting and training "
           f"({report['env_steps_per_s']:.1f} environment steps/s with updates and compilation, "
           f"evaluations excluded); {report['num_params']:,} parameters.", '']
  if report['curve']:
    lines += ['Planner (EMA parameters, no exploration noise) on held-out goals during training:',
              '', '| environment steps | episodes | success | 95% CI | mean return (an episode '
              'stops at its success) |',
              '| --- | --- | --- | --- | --- |']
    lines += [f"| {r['env_steps']:,} | {r['episodes']} | {r['success_rate']:.2f} | "
              f"[{r['ci95'][0]:.2f}, {r['ci95'][1]:.2f}] | {r['mean_return']:.1f} |"
              for r in report['curve']]
    lines.append('')
  lines += acting_md(report['acting'])
  return runs.summary_md(f"LD-MPC online on {report['task']}", lines, report,
                         'Final evaluation, EMA parameters: ', 'training')
