#!/usr/bin/env bash
# Does the dense online program of this checkout make exactly what it made at an older commit? (Issue 70's "dense reward
# is not harmed", short of re-running the 100k-step door-open run: 16,465 s for three seeds on the 2-core CPU.)
# Runs `door_open_online.py:PRESET` (dense reward, the defaults) at BASE and at the checkout, then compares the training
# episodes, the losses, the evaluation and every array of the replay buffers; only timing columns may differ.
# Usage, from the repository root: bash lab/regression/same_dense_program.sh [BASE [PRESET [FLAG ...]]]
# (defaults 83ada3e and smoke). The :cpu sizes over two random and two planner waves (about 6 min a side):
#   ... 83ada3e cpu --config.online.env_steps=800 --config.online.seed_steps=400 --config.online.num_envs=2 \
#   --config.online.episode_steps=100 --config.eval.episodes=0 --config.online.eval_every=100000
set -euo pipefail
BASE=${1:-83ada3e}; PRESET=${2:-smoke}; shift $(( $# < 2 ? $# : 2 ))
HERE=$(pwd); TMP=$(mktemp -d); trap 'git worktree remove --force "$TMP/base" >/dev/null 2>&1 || true; rm -rf "$TMP"' EXIT
git worktree add -f "$TMP/base" "$BASE" --detach >/dev/null 2>&1
PY=${PY:-$HERE/.venv/bin/python}
for side in base here; do
  src=$HERE; [ $side = base ] && src=$TMP/base
  (cd "$src" && PYTHONPATH="$src" "$PY" -m experiments.train --config=ld_mpc_jax/configs/door_open_online.py:$PRESET \
    --workdir="$TMP/run_$side" "$@" > "$TMP/$side.log" 2>&1) || { tail -5 "$TMP/$side.log"; exit 1; }
done
"$PY" - "$TMP/run_base" "$TMP/run_here" <<'PY'
import glob, os, sys
import numpy as np
base, here = sys.argv[1:]
TIMING = {'env_steps_per_s', 'decisions_per_s'}
same = True
for name in ('online.csv', 'losses.csv', 'eval.csv', 'episodes.csv'):
  there = [os.path.exists(os.path.join(d, name)) for d in (base, here)]
  if not any(there):  # E.g. eval.csv of a run with --config.eval.episodes=0.
    continue
  if not all(there):
    print(f'{name}: written by one side only'); same = False; continue
  a = np.genfromtxt(os.path.join(base, name), delimiter=',', names=True, dtype=None, encoding=None)
  b = np.genfromtxt(os.path.join(here, name), delimiter=',', names=True, dtype=None, encoding=None)
  fields = [f for f in a.dtype.names if f not in TIMING]
  ok = a.shape == b.shape and all(np.array_equal(a[f], b[f], equal_nan=a[f].dtype.kind == 'f') for f in fields)
  print(f'{name}: {len(np.atleast_1d(a))} rows, {"identical" if ok else "DIFFERENT"} (timing columns left out)')
  same &= ok
for path in sorted(glob.glob(os.path.join(base, 'online', 'buffer_*.npz'))):
  a, b = np.load(path), np.load(os.path.join(here, 'online', os.path.basename(path)))
  arrays = [k for k in a.files if k != 'metadata_json']
  ok = all(np.array_equal(a[k], b[k]) for k in arrays)
  print(f'{os.path.basename(path)}: {", ".join(arrays)}: {"identical" if ok else "DIFFERENT"}')
  same &= ok
print('the same program' if same else 'the programs differ')
sys.exit(0 if same else 1)
PY
