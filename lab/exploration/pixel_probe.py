"""What a pixel run's latent encodes (issue 105): ridge-probe R^2 (held-out episodes) of Meta-World state groups from z,
on episodes of the run's own rendered dataset. Usage, from the repository root (MUJOCO_GL not needed):
  .venv/bin/python lab/exploration/pixel_probe.py STATE_DATASET IMAGE_DATASET RUN_DIR [RUN_DIR ...]
IMAGE_DATASET: the `..._px48x1_corner2.npz` rendered beside STATE_DATASET (one frame); a run with model.proprio reads the
robot's state after the frame, as it was trained.
"""
import sys
import numpy as np
from ld_mpc_jax import data, encode
from ld_mpc_jax.data.pixels import with_proprio
from ld_mpc_jax.learn import checkpointing

GROUPS = {'hand': slice(0, 3), 'gripper': slice(3, 4), 'handle_pos': slice(4, 7), 'goal': slice(36, 39)}


def r2(ztr, ytr, zte, yte, lam=1e-3):
  mu, sd = ztr.mean(0), ztr.std(0) + 1e-8
  a = np.c_[(ztr - mu) / sd, np.ones(len(ztr))]; b = np.c_[(zte - mu) / sd, np.ones(len(zte))]
  w = np.linalg.solve(a.T @ a + lam * len(a) * np.eye(a.shape[1]), a.T @ ytr)
  res = ((b @ w - yte) ** 2).sum(0); tot = ((yte - ytr.mean(0)) ** 2).sum(0)
  return 1 - res.sum() / max(tot.sum(), 1e-12)


states, images = data.load(sys.argv[1]), data.load(sys.argv[2])
rng = np.random.default_rng(0)
eps = rng.permutation(states.num_episodes)[:80]
rows = lambda ids: np.concatenate([np.arange(states.episode_starts[e], states.episode_starts[e] + states.episode_lengths[e] + 1)
                                   for e in ids])
tr, te = rows(eps[:64]), rows(eps[64:])
for workdir in sys.argv[3:]:
  config, params, step = checkpointing.load_for_evaluation(workdir)
  obs = (with_proprio(images, states) if config.model.proprio else images).observations
  z = lambda r: np.concatenate([np.asarray(encode(params, np.asarray(obs[r[i:i + 2048]], np.float32)))
                                for i in range(0, len(r), 2048)])
  ztr, zte = z(tr), z(te)
  s = np.linalg.svd(ztr - ztr.mean(0), compute_uv=False); p = s**2 / (s**2).sum()
  out = ', '.join(f'{g} {r2(ztr, states.observations[tr, sl], zte, states.observations[te, sl]):.3f}'
                  for g, sl in GROUPS.items())
  print(f'{workdir} (update step {step}, proprio {bool(config.model.proprio)}): effective rank '
        f'{np.exp(-(p * np.log(p + 1e-12)).sum()):.1f}; R2 {out}')
