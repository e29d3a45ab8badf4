#!/usr/bin/env bash
# Sparse push-v3, 5 demonstrations, the v3 recipe (docs/sparse.md), three seeds in one run: the 60k run
# (../v3_5demos_7b652a9/run.sh, same workdir) continued from its 60k checkpoint to 100k simulator steps
# (= 50k TD-MPC2 decisions); only online.env_steps changed (--continue_with_changes keeps config.1.json).
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 7b652a9
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3   --workdir=runs/sparse_push_v3 --config.train.num_seeds=3 --config.online.reward=sparse   --config.online.demos=5 --config.online.env_steps=100000 --config.online.eval_every=20000   --config.online.act_num_gaussian=0 --config.online.act_iterations=0   --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True   --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max   --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1   --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --continue_with_changes
