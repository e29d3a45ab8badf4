"""The per-decision trace of C8M1 on MT10 peg-insert-side, training seed 1 (trace_plan.py's
output): for each episode, every 10 decisions the share departing, J of the actor prior's own
sequence, the winner's gain over it, the reward and Meta-World's terms, and the decision where
J of the actor prior's sequence first falls more than 10% below its peak so far.

  python results/records/fallback/trace_summary.py results/records/fallback/trace_peg_seed1.json.gz
"""
import gzip
import json
import sys

import numpy as np

with gzip.open(sys.argv[1], 'rt') as f:
  episodes = json.load(f)['episodes']
for e in episodes:
  rows = e['decisions']
  ja = np.array([r['j_actor'] for r in rows])
  peak = np.maximum.accumulate(ja)
  fall = np.flatnonzero(ja < peak - 0.1 * np.abs(peak))
  print(f"episode {e['episode']}: {'solved at ' + str(e['first_success']) if e['success'] else 'lost'}"
        f", {len(rows)} decisions; J of the actor prior's sequence first 10% below its peak at "
        f"{int(fall[0]) if fall.size else 'never'}")
  print('| decisions | departing | J, actor prior | gain of the executed | reward | obj_to_target | grasp_success | near_object |')
  print('| --- | --- | --- | --- | --- | --- | --- | --- |')
  for a in range(0, len(rows), 10):
    s = rows[a:a + 10]
    m = lambda k: np.mean([r[k] for r in s])
    print(f"| {a}-{a + len(s) - 1} | {m('departed'):.1f} | {m('j_actor'):.0f} | "
          f"{np.mean([r['j_exec'] - r['j_actor'] for r in s]):.1f} | {m('reward'):.2f} | "
          f"{m('obj_to_target'):.3f} | {m('grasp_success'):.1f} | {m('near_object'):.1f} |")
  print()
