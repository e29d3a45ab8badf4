"""Pools evaluation JSONs (experiments.evaluate --out) over seeds: successes, rate, Wilson CI.

  python -m experiments.pool_evals runs/evals/warm_seed0.json runs/evals/warm_seed1.json ...

Prints one line per policy mode found in the files: successes / episodes, the pooled success
rate with its 95% Wilson interval, and the per-file rates in the order given.
"""

import json
import sys

from ld_mpc_jax.evaluation import wilson_interval


def pool(results: list) -> dict:
  """[evaluate JSON dicts] -> {mode: {successes, episodes, success_rate, success_ci95, rates}}."""
  pooled = {}
  for result in results:
    for mode, r in result['modes'].items():
      p = pooled.setdefault(mode, dict(successes=0, episodes=0, rates=[]))
      p['successes'] += int(round(r['success_rate'] * result['episodes']))
      p['episodes'] += result['episodes']
      p['rates'].append(r['success_rate'])
  for p in pooled.values():
    p['success_rate'] = p['successes'] / p['episodes']
    p['success_ci95'] = wilson_interval(p['successes'], p['episodes'])
  return pooled


def main(paths: list) -> None:
  if not paths:
    raise SystemExit(__doc__)
  results = []
  for path in paths:
    with open(path) as f:
      results.append(json.load(f))
  for mode, p in pool(results).items():
    lo, hi = p['success_ci95']
    rates = ', '.join(f'{r:.2f}' for r in p['rates'])
    print(f"{mode}: {p['successes']}/{p['episodes']} = {p['success_rate']:.3f} "
          f"[{lo:.2f}, {hi:.2f}] (per file: {rates})")


if __name__ == '__main__':
  main(sys.argv[1:])
