#!/usr/bin/env bash
# Issue 70, "a reward head that sees rare successes": the sparse door-open recipe of ../v3_bc_actor_safe_22ad14c (5
# demonstrations, the same flags) with a class-balanced reward head (loss.reward_balance=1: the batch's successes weigh as
# much in total as its zeros). Three seeds in one run, 30,400 simulator steps. Run from a worktree at commit 4a48b82
# (git worktree add ../wt_4a48b82 4a48b82); 4,182 s for the three seeds together, alone on the 2-core CPU (a slow day:
# 7.8-8.2 simulator steps/s per seed, against 14-15 for the run it pairs with).
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/sparse_door_balance \
  --config.train.num_seeds=3 --config.online.reward=sparse --config.online.demos=5 --config.online.env_steps=30000 \
  --config.online.eval_every=10000 --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --config.loss.reward_balance=1
# Paired against the run without balancing (the same held-out episodes; its policies tagged #balance):
R=results/sparse_door_open; for s in 0 1 2; do F+=" $R/v3_bc_actor_safe_22ad14c/seed${s}_episodes.csv.gz+$R/balance_4a48b82/seed${s}_episodes.csv.gz#balance"; done
python -m experiments.report $F
# The reward head's calibration on held-out successes (the actor prior acting; results/reward_calibration/):
python -m experiments.diagnose reward --workdir=runs/sparse_door_balance/seed0 --workdir=runs/sparse_door_balance/seed1 \
  --workdir=runs/sparse_door_balance/seed2 --episodes=50 --out=door_balance_actor.json
