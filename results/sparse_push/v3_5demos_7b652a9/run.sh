#!/usr/bin/env bash
# Sparse push-v3, 5 demonstrations, the v3 recipe of sparse door-open (docs/sparse.md), three seeds in one run,
# 60k simulator steps (= 30k TD-MPC2 decisions).
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 7b652a9
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3   --workdir=runs/sparse_push_v3 --config.train.num_seeds=3 --config.online.reward=sparse   --config.online.demos=5 --config.online.env_steps=60000 --config.online.eval_every=20000   --config.online.act_num_gaussian=0 --config.online.act_iterations=0   --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True   --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max   --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1   --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000
