#!/usr/bin/env bash
# Sparse door-open with 5 demonstrations, :cpu_tanh, 50k simulator steps, three training seeds side by side.
cd <worktree at 463d416>
for s in 0 1 2; do
  nohup .venv/bin/python -m experiments.train --config=door_open_online.py:cpu_tanh     --workdir=runs/sparse_demos/seed$s --config.seed=$s --config.online.reward=sparse     --config.online.demos=5 --config.online.env_steps=50000 > runs/sparse_demos/seed$s.log 2>&1 &
done
wait
