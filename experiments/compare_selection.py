"""Compares planner selection settings against the actor prior, on the same held-out episodes.

  python -m experiments.compare_selection --workdirs=runs/obj/door_open_weak/seed0,... \\
      --variant=argmax: \\
      --variant=safe1:plan.safe_selection=True,plan.safe_margin=1.0 \\
      --variant=safe1_k4:plan.safe_selection=True,plan.safe_margin=1.0,plan.num_candidates=4,plan.num_prior_candidates=1 \\
      [--baselines=actor,proposal] [--episodes=50] [--seed=0] --out=runs/obj/weak_selection.json

Each workdir is one training seed (its latest checkpoint, EMA parameters). Every variant of the
planner (a name and its config overrides) and every baseline runs on the same episodes of the
held-out goals; a multi-task checkpoint runs every task. Each evaluation is cached under
<workdir>/evals/ (an interrupted comparison resumes), and the per-episode records go to --out
with a markdown table beside it (--out with .md): per variant, pooled success, the rate per
training seed, the share of decisions that departed from the actor prior's own sequence, and the
paired test against the actor prior pooled and per seed (exact McNemar; "behind" is the largest
number of episodes a seed's planner lost to its actor prior).
"""

import json
import os

from absl import app, flags, logging

from experiments import cli

_WORKDIRS = flags.DEFINE_list('workdirs', None, 'Training run directories (one per seed).')
_VARIANTS = flags.DEFINE_multi_string('variant', ['argmax:'],
                                      'NAME:field=value,field=value planner settings.')
_BASELINES = flags.DEFINE_list('baselines', ['actor', 'proposal'], 'Other policies.')
# allow_override: the test session imports this module beside experiments.ablations, which
# defines --episodes too (a launcher process loads only one of them).
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Held-out episodes per seed (and task).',
                                 allow_override=True)
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed.')
_OUT = flags.DEFINE_string('out', None, 'JSON output; the table goes beside it (.md).')
_OVERWRITE = flags.DEFINE_bool('overwrite', False, 'Replace an existing --out file.')
flags.mark_flags_as_required(['workdirs', 'out'])


def parse_variant(text: str):
  """'safe1:plan.safe_selection=True,plan.safe_margin=1.0' -> ('safe1', {field: value})."""
  name, sep, rest = text.partition(':')
  if not sep or not name:
    raise ValueError(f'--variant must be NAME:field=value,..., got {text!r}')
  items = {}
  for item in filter(None, rest.split(',')):
    field, eq, value = item.partition('=')
    if not eq:
      raise ValueError(f'--variant {name!r}: {item!r} is not field=value')
    items[field.strip()] = value.strip()
  return name, items


def evaluate_run(workdir: str, variants, baselines, episodes: int, seed: int) -> list:
  """Records of every variant ('plan[NAME]') and baseline on one checkpoint's held-out episodes."""
  from ld_mpc_jax import checkpointing, multitask_eval
  from ld_mpc_jax.config_checks import validate_config
  from experiments.overrides import with_overrides
  config, params, step = checkpointing.load_for_evaluation(workdir)
  records = []
  runs = [(f'plan[{name}]', 'plan', with_overrides(config, items)) for name, items in variants]
  runs += [(mode, mode, config) for mode in baselines]
  for policy, mode, cfg in runs:
    validate_config(cfg)
    _, evaluate = multitask_eval.grid(cfg, ('held_out',))
    recs = evaluate(cfg, params, workdir, step, (mode,), ('held_out',), (seed,), episodes,
                    run=workdir)
    for r in recs:
      r['policy'] = policy
    records.extend(recs)
  return records


def table(records: list, anchor: str = 'actor') -> list:
  """Per policy: pooled and per-run success, departures, and the paired test against `anchor`."""
  from ld_mpc_jax import stats
  policies = list(dict.fromkeys(r['policy'] for r in records))
  runs = list(dict.fromkeys(r['run'] for r in records))
  base = stats.select(records, policy=anchor)
  rows = []
  for policy in policies:
    mine = stats.select(records, policy=policy)
    row = dict(policy=policy, **stats.summarize(mine),
               per_run=[float(sum(r['success'] for r in stats.select(mine, run=run))
                              / max(len(stats.select(mine, run=run)), 1)) for run in runs])
    if all('departures' in r for r in mine):
      row['departure_share'] = (sum(r['departures'] for r in mine)
                                / max(sum(r['length'] for r in mine), 1))
    if base and policy != anchor:
      row['vs_anchor'] = stats.paired(mine, base)
      per_run = [stats.paired(stats.select(mine, run=run), stats.select(base, run=run))
                 for run in runs]
      row['vs_anchor_per_run'] = per_run
      row['most_behind'] = max(m['b_only'] - m['a_only'] for m in per_run)
    rows.append(row)
  return rows


def markdown(rows: list, anchor: str = 'actor') -> str:
  lines = [f'| policy | held-out success, pooled | per training seed | decisions departing '
           f'from the actor prior | vs {anchor}: only this / only {anchor}, p | per seed | '
           f'most episodes behind {anchor} on one seed |', '| --- ' * 7 + '|']
  for r in rows:
    dep = f"{r['departure_share']:.2f}" if 'departure_share' in r else ''
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


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.run_files import git_commit
  with cli.one_line_errors():
    cli.check_new_output(_OUT.value, _OVERWRITE.value)
    variants = [parse_variant(v) for v in _VARIANTS.value]
    if len({name for name, _ in variants}) != len(variants):
      raise ValueError('--variant names must be distinct')
    missing = [w for w in _WORKDIRS.value if not os.path.isdir(w)]
    if missing:
      raise FileNotFoundError(f'no run directory {missing[0]}')
  records = []
  for workdir in _WORKDIRS.value:
    records.extend(evaluate_run(workdir, variants, _BASELINES.value, _EPISODES.value,
                                _SEED.value))
  anchor = 'actor' if 'actor' in _BASELINES.value else records[0]['policy']
  rows = table(records, anchor)
  md = markdown(rows, anchor)
  print(md)
  out = dict(workdirs=_WORKDIRS.value, variants=_VARIANTS.value, baselines=_BASELINES.value,
             episodes=_EPISODES.value, seed=_SEED.value, git_commit=git_commit(), rows=rows,
             records=records)
  os.makedirs(os.path.dirname(os.path.abspath(_OUT.value)), exist_ok=True)
  with open(_OUT.value, 'w') as f:
    json.dump(out, f, indent=1)
  with open(os.path.splitext(_OUT.value)[0] + '.md', 'w') as f:
    f.write(md)
  print(f'wrote {_OUT.value}')


if __name__ == '__main__':
  app.run(main)
