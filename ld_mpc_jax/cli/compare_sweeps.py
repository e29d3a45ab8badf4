"""Pairs two sweeps of the same task and evaluation episodes: does a config change help?

  python -m experiments.report sweeps A/sweep.json B/sweep.json [--policies=plan] [--split=train]
  python -m experiments.report sweeps A/sweep.json A/seed0/eval_x.json,A/seed1/eval_x.json --policies=plan
  python -m experiments.report sweeps A/seed1/episodes.csv runs/online/ft/episodes.csv  # before/after

A and B are `experiments.train` outputs (for example the same preset with and without a config
override), or `experiments.evaluate --out` JSONs of the sweep's seed workdirs: several files
joined by commas count as one side (their records carry the training seed as `run`), e.g.
`B=runs/x/seed0/eval_k0.json,runs/x/seed1/eval_k0.json` for an evaluation-time override. A run's
own `episodes.csv` (training or online fine-tuning) is a side too, and so is an
`experiments.evaluate selection --out` JSON (its records name their workdir and its training
seed, read from the workdir's config.json for older files; choose its planners with e.g.
`--policies='plan[argmax]'`).
`--policies='plan[safe1]=plan[safe1_k4]'` pairs A's first policy with B's second: two variants
evaluated in different files on the same checkpoints and episodes. An episode of A pairs with
the episode of B with the same training seed, goal split, evaluation seed and episode index: the
same goal and reset seed, a checkpoint trained with the same seed under each config. Prints both
success rates over the paired episodes and the exact McNemar test on the discordant pairs, per
policy. Paired episodes whose recorded goals differ end the program with one line: they were not
the same episodes.
"""

import json
import os

from absl import app, flags

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.cli.pool import read_records
from ld_mpc_jax.ops import stats

_POLICIES = flags.DEFINE_list('policies', ['plan', 'actor', 'proposal'],
                               'Policies to pair; A_POLICY=B_POLICY pairs two different ones.')
_SPLIT = flags.DEFINE_string('split', 'held_out', 'Goal split.')


def read_side(spec: str) -> dict:
  """{'records': ...} of one file, or of several joined by commas. A record whose `run` is a
  workdir (an `experiments.evaluate selection` JSON) gets that workdir's training seed instead, so
  that checkpoints of two configs pair by seed as a sweep's do."""
  seeds = {}
  records = []
  for path in spec.split(','):
    for r in read_records(path):
      if isinstance(r.get('run'), str):
        if 'train_seed' in r:
          seeds[r['run']] = r['train_seed']
        elif r['run'] not in seeds:  # Written before records carried it: the workdir's config.
          seeds[r['run']] = _training_seed(r['run'], path)
        r = {**r, 'run': seeds[r['run']]}
      records.append(r)
  return {'records': records}


def _training_seed(workdir: str, path: str) -> int:
  """config.seed of the training run at `workdir`, named by a record of `path`."""
  config = os.path.join(workdir, 'config.json')
  try:
    with open(config) as f:
      return int(json.load(f)['seed'])
  except (OSError, ValueError, KeyError) as err:
    cli.fail(f'{path} names the run {workdir}, whose training seed cannot be read from '
             f'{config}: {err!r}')


def paired_rows(a: dict, b: dict, policies, split: str) -> list:
  """One row per policy: episodes, success of A and B on them, McNemar (A only, B only, p)."""
  pick = lambda sweep, name: {tuple(r.get(k) for k in stats.EPISODE_KEY): r
                              for r in sweep['records']
                              if r['policy'] == name and r['split'] == split}
  rows = []
  for policy in policies:
    name_a, _, name_b = policy.partition('=')
    ra, rb = pick(a, name_a), pick(b, name_b or name_a)
    keys = sorted(set(ra) & set(rb))
    if not keys:
      continue
    for k in keys:
      goals = ra[k].get('goal_id'), rb[k].get('goal_id')
      if None not in goals and goals[0] != goals[1]:
        cli.fail(f'{policy} episode {k}: goal {goals[0]} in A but {goals[1]} in B, so the two '
                 'sides did not run the same episodes')
    ra = {k: r['success'] for k, r in ra.items()}
    rb = {k: r['success'] for k, r in rb.items()}
    test = stats.mcnemar_exact([ra[k] for k in keys], [rb[k] for k in keys])
    rows.append(dict(policy=policy, episodes=len(keys), a=sum(ra[k] for k in keys),
                     b=sum(rb[k] for k in keys), **test,
                     seeds=sorted({k[0] for k in keys})))
  return rows


def main(argv):
  if len(argv) != 3:
    cli.fail('give two sweep JSONs: python -m experiments.report sweeps A/sweep.json B/sweep.json')
  sweeps = [read_side(side) for side in argv[1:]]
  rows = paired_rows(*sweeps, _POLICIES.value, _SPLIT.value)
  if not rows:
    cli.fail(f'no paired {_SPLIT.value} episodes between {argv[1]} and {argv[2]}')
  print(f'A = {argv[1]}\nB = {argv[2]}\n')
  print('| policy | training seeds | paired episodes | A | B | only A | only B | p |')
  print('| --- | --- | ---: | --- | --- | ---: | ---: | ---: |')
  for r in rows:
    n = r['episodes']
    print(f"| {r['policy']} | {','.join(map(str, r['seeds']))} | {n} | {r['a']}/{n} = "
          f"{r['a'] / n:.2f} | {r['b']}/{n} = {r['b'] / n:.2f} | {r['a_only']} | "
          f"{r['b_only']} | {r['p_value']:.2g} |")
