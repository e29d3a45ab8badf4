"""Statistics of per-episode evaluation records: rates, Wilson intervals, paired McNemar tests.

A record is a dict with at least `success` (0/1) and the fields that identify its episode
(`EPISODE_KEY`); records of two policies evaluated on the same episodes pair up on those fields.
"""

from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

# The fields that identify an episode; `run` names the checkpoint (e.g. the training seed),
# `task` the task of a multi-task agent's episode (absent, so None, for a single task).
EPISODE_KEY = ('run', 'task', 'split', 'eval_seed', 'episode')


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> List[float]:
  """Wilson score interval [lo, hi] of a binomial proportion (scipy.stats.binomtest)."""
  if n <= 0:
    return [0.0, 1.0]
  from scipy import stats as sps  # Here, not at the top: scipy.stats takes seconds to import.
  ci = sps.binomtest(int(successes), int(n)).proportion_ci(confidence, method='wilson')
  return [float(ci.low), float(ci.high)]


def summarize(records: Sequence[dict]) -> Dict[str, float]:
  """Pooled counts of records: successes, episodes, rate, Wilson interval, means."""
  n = len(records)
  k = int(sum(int(r['success']) for r in records))
  out = dict(successes=k, episodes=n, success_rate=k / n if n else float('nan'),
             success_ci95=wilson_interval(k, n))
  for name in ('return', 'length', 'env_steps'):
    if n and all(name in r for r in records):
      out[f'mean_{name}'] = float(np.mean([r[name] for r in records]))
  return out


def mcnemar_exact(a: Sequence[int], b: Sequence[int]) -> Dict[str, float]:
  """Exact (binomial) McNemar test of paired 0/1 outcomes a[i], b[i] of the same episodes.

  Returns dict(n, a_only (a succeeded, b failed), b_only, p_value): the two-sided p-value of
  `a_only` successes out of the a_only + b_only discordant pairs under p = 1/2 (1.0 when there
  are none).
  """
  a, b = np.asarray(a, int), np.asarray(b, int)
  if a.shape != b.shape:
    raise ValueError(f'paired outcomes need the same episodes, got {a.shape} and {b.shape}')
  a_only, b_only = int(np.sum((a == 1) & (b == 0))), int(np.sum((a == 0) & (b == 1)))
  discordant = a_only + b_only
  from scipy import stats as sps  # pylint: disable=g-import-not-at-top
  p = sps.binomtest(a_only, discordant, 0.5).pvalue if discordant else 1.0
  return dict(n=int(a.size), a_only=a_only, b_only=b_only, p_value=float(p))


def episode_key(record: dict) -> Tuple:
  """The fields (EPISODE_KEY) that name a record's episode; equal keys, the same episode."""
  return tuple(record.get(k) for k in EPISODE_KEY)


def paired(records_a: Iterable[dict], records_b: Iterable[dict]) -> Dict[str, float]:
  """McNemar test of two policies on the episodes both were evaluated on (matched by key)."""
  by_key = {episode_key(r): int(r['success']) for r in records_b}
  pairs = [(int(r['success']), by_key[episode_key(r)]) for r in records_a
           if episode_key(r) in by_key]
  if not pairs:
    raise ValueError('the two sets of records share no episode')
  a, b = zip(*pairs)
  return mcnemar_exact(a, b)


def select(records: Iterable[dict], **fields) -> List[dict]:
  """The records whose fields equal the given values (None matches anything)."""
  return [r for r in records
          if all(v is None or r.get(k) == v for k, v in fields.items())]


def spread(records: Sequence[dict], field: str = 'run') -> Dict[str, Optional[float]]:
  """Success rate per value of `field` (e.g. per training seed), with their mean and std."""
  groups: Dict[str, List[int]] = {}
  for r in records:
    groups.setdefault(str(r.get(field)), []).append(int(r['success']))
  rates = {k: float(np.mean(v)) for k, v in sorted(groups.items())}
  values = list(rates.values())
  return dict(rates=rates, mean=float(np.mean(values)) if values else None,
              std=float(np.std(values, ddof=1)) if len(values) > 1 else None)
