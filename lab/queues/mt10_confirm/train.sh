#!/bin/bash
# MT10 `mixed`, mt10.py:cpu, one training seed (commit 1cd6f29, worktree /work/wt40).
s=$1
cd /work/wt40 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
python -m experiments.train --config=experiments/configs/mt10.py:cpu \
  --config.eval.episodes=0 --config.seed=$s \
  --workdir=/work/runs31/mt10/seed$s > /work/runs31/train_seed$s.log 2>&1
echo "$(date +%T) seed $s exit $?" >> /work/runs31/train_done.log
