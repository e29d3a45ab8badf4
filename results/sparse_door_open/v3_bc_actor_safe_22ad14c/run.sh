#!/usr/bin/env bash
# Sparse door-open, 5 demonstrations: the actor prior clones them (loss.w_demo_bc), the seed waves act with it,
# safe selection (the recommended gates) while acting and evaluating; three seeds in one run, 30k simulator steps.
cd <worktree at the commit>
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu_tanh   --workdir=runs/sparse_demos_v3/run --config.train.num_seeds=3 --config.online.reward=sparse   --config.online.demos=5 --config.online.env_steps=30000 --config.online.eval_every=10000   --config.online.act_num_gaussian=0 --config.online.act_iterations=0   --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True   --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max   --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1   --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000
