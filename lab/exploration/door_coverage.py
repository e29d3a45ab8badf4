"""Door-open exploration coverage of a buffer file, in chunks of its episodes: the hand's closest approach to the handle
and how far the handle moved. Usage: .venv/bin/python lab/exploration/door_coverage.py RUN_DIR/online/buffer_N.npz ...
"""
import sys
import numpy as np
from ld_mpc_jax import data
for path in sys.argv[1:]:
  ds = data.load(path)
  rows = []
  for e in range(ds.num_episodes):
    o = ds.episode(e)['obs']
    d = np.linalg.norm(o[:, 0:3] - o[:, 4:7], axis=1).min()
    m = np.linalg.norm(o[:, 4:7] - o[0, 4:7], axis=1).max()
    opened = (o[0, 4] - o[:, 4]).max()  # Success: the handle's x within 0.08 of x0 - 0.3.
    rows.append((d, m, o[:, 0:3].min(0), o[:, 0:3].max(0), opened))
  d = np.array([r[0] for r in rows]); m = np.array([r[1] for r in rows]); op = np.array([r[4] for r in rows])
  print(path, ds.num_episodes, 'episodes')
  for chunk in np.array_split(np.arange(len(rows)), min(8, len(rows))):
    print(f'  ep {chunk[0]:3d}-{chunk[-1]:3d}: min hand-handle {np.median(d[chunk]):.3f} (best {d[chunk].min():.3f}); handle moved max {m[chunk].max():.4f}, >1cm {np.mean(m[chunk]>0.01):.2f}; opened max {op[chunk].max():.3f} (success needs 0.22)')
  lo = np.min([r[2] for r in rows], 0); hi = np.max([r[3] for r in rows], 0)
  print('  hand range', np.round(lo, 2), np.round(hi, 2), ' handle at', np.round(ds.episode(0)['obs'][0, 4:7], 3))
