"""What a run's latent encodes: ridge-probe R^2 (held-out episodes of its last buffer) of Meta-World observation groups
from z, and of the handle's displacement within an episode (the door's angle). Usage, from the repository root:
  .venv/bin/python lab/exploration/latent_probe.py RUN_DIR [RUN_DIR ...]
"""
import sys, glob, os
import numpy as np
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax import data, encode

GROUPS = {'hand': slice(0, 3), 'gripper': slice(3, 4), 'obj1_pos': slice(4, 7), 'obj1_quat': slice(7, 11), 'goal': slice(36, 39)}

def r2(ztr, ytr, zte, yte, lam=1e-3):
  mu, sd = ztr.mean(0), ztr.std(0) + 1e-8
  a = np.c_[(ztr - mu) / sd, np.ones(len(ztr))]; b = np.c_[(zte - mu) / sd, np.ones(len(zte))]
  w = np.linalg.solve(a.T @ a + lam * len(a) * np.eye(a.shape[1]), a.T @ ytr)
  res = ((b @ w - yte) ** 2).sum(0); tot = ((yte - ytr.mean(0)) ** 2).sum(0)
  return 1 - res.sum() / max(tot.sum(), 1e-12), yte.std(0).mean()

for workdir in sys.argv[1:]:
  config, params, step = checkpointing.load_for_evaluation(workdir)
  bufs = sorted(glob.glob(os.path.join(workdir, 'online', 'buffer_*.npz')), key=lambda p: int(p.split('_')[-1][:-4]))
  ds = data.load(bufs[-1])
  eps = [ds.episode(e)['obs'] for e in range(ds.num_episodes)]
  rng = np.random.default_rng(0); idx = rng.permutation(len(eps)); cut = int(0.8 * len(eps))
  tr = np.concatenate([eps[i] for i in idx[:cut]]); te = np.concatenate([eps[i] for i in idx[cut:]])
  ztr, zte = (np.asarray(encode(params, x)) for x in (tr, te))
  print(f'{workdir}: update step {step}, {len(eps)} episodes, buffer {bufs[-1]}, latent {ztr.shape[1]}')
  s = np.linalg.svd(ztr - ztr.mean(0), compute_uv=False); p = s**2 / (s**2).sum()
  print(f'  latent: mean per-dim std {ztr.std(0).mean():.4f}, effective rank {np.exp(-(p*np.log(p+1e-12)).sum()):.1f}, top-3 var share {p[:3].sum():.2f}')
  for g, sl in GROUPS.items():
    rz, sd = r2(ztr, tr[:, sl], zte, te[:, sl])
    print(f'  {g:10s} R2 {rz:6.3f}   (held-out std {sd:.4f})')
  # Within-episode handle displacement (the door's angle), on all steps.
  disp = lambda ids: np.concatenate([eps[i][:, 4:7] - eps[i][:1, 4:7] for i in ids])
  rz, sd = r2(ztr, disp(idx[:cut]), zte, disp(idx[cut:]))
  print(f'  handle displacement R2 {rz:6.3f} (held-out std {sd:.4f})')
