#!/bin/bash
# door-open `medium`, door_open.py:cpu, three training seeds side by side (commit 1ca1c8b, worktree /work/wt39).
cd /work/wt39 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
for s in 0 1 2; do
  python -m experiments.train --config=experiments/configs/door_open.py:cpu --config.data.preset=medium \
    --config.eval.splits=held_out --config.eval.episodes=0 --config.seed=$s \
    --workdir=/work/runs30/door_medium/seed$s > /work/runs30/train_seed$s.log 2>&1 &
done
wait
echo "$(date +%T) all trained"
