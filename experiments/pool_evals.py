"""Pools evaluation JSONs (experiments.evaluate --out) from per-episode records.

  python -m experiments.pool_evals runs/a/evaluation.json runs/b/evaluation.json ...

Each file's records count once (a file is one `run`, named by its path, so episodes of different
checkpoints never pair up). Prints per goal split and policy the pooled successes with a Wilson
interval and the rate of each file, then exact McNemar tests between policies on the same
episodes. Multi-task evaluations (records with a `task`) first get the per-task table of
`multitask_eval`, pooled over the files.
"""

import json
import sys

from experiments import cli
from ld_mpc_jax import evaluation_suite, multitask_eval


def pool(results: list, names: list) -> dict:
  """[evaluate JSON dicts], [their names] -> evaluation_suite.summarize of all their records."""
  records = []
  for result, name in zip(results, names):
    for r in result['records']:
      records.append({**r, 'run': name})
  return evaluation_suite.summarize(records)


def read_json(path: str) -> dict:
  """The JSON file at `path`; a file that cannot be read ends the program with one line, code 2."""
  try:
    with open(path) as f:
      return json.load(f)
  except (OSError, json.JSONDecodeError) as err:
    cli.fail(f'cannot read {path}: {err}')


def main(paths: list) -> None:
  if not paths:
    cli.fail('give one or more evaluation JSONs: python -m experiments.pool_evals A.json ...')
  results = []
  for path in paths:
    results.append(read_json(path))
    if 'records' not in results[-1]:
      cli.fail(f'{path} has no per-episode records (written by an older evaluate?)')
  records = [r for res in results for r in res['records']]
  tasks = list(dict.fromkeys(r.get('task') for r in records))
  if len(tasks) > 1 and None in tasks:
    cli.fail('the files mix multi-task and single-task evaluations')
  if tasks != [None]:
    print(multitask_eval.markdown(multitask_eval.per_task(records, tasks), tasks))
  print(evaluation_suite.markdown(pool(results, paths)), end='')


if __name__ == '__main__':
  main(sys.argv[1:])
