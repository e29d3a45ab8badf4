"""Peg-insert-side, MT10 training seed 1 (peg_seed1.json): which episodes each planner setting
lost, and its share of decisions departing from the actor prior in solved and in lost episodes.

  python results/records/mt10_confirm/peg_lost.py results/records/mt10_confirm/peg_seed1.json
"""
import collections
import json
import sys

records = json.load(open(sys.argv[1]))['records']
by = collections.defaultdict(dict)
for r in records:
  by[r['policy']][r['episode']] = r
actor = by['actor']
print('| policy | episodes lost (actor prior: decisions to success) | departing, solved episodes | departing, lost episodes |')
print('| --- | --- | --- | --- |')
for policy, eps in by.items():
  if not policy.startswith('plan'):
    continue
  lost = sorted(e for e, r in eps.items() if not r['success'])
  share = lambda rs: sum(r['departures'] for r in rs) / max(1, sum(r['length'] for r in rs))
  solved_rs = [r for r in eps.values() if r['success']]
  lost_rs = [eps[e] for e in lost]
  lost_text = ', '.join('%d (%d)' % (e, actor[e]['first_success']) for e in lost)
  print(f'| {policy} | {lost_text} | {share(solved_rs):.2f} | {share(lost_rs):.2f} |')
