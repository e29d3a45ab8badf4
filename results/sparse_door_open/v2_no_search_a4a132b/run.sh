#!/usr/bin/env bash
# Sparse door-open, 5 demonstrations, acting without the broad search; three seeds in one run.
cd <worktree at the commit>
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu_tanh   --workdir=runs/sparse_demos_v2/run --config.train.num_seeds=3 --config.online.reward=sparse   --config.online.demos=5 --config.online.env_steps=50000   --config.online.act_num_gaussian=0 --config.online.act_iterations=0
