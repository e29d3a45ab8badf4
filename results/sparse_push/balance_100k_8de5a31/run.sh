#!/usr/bin/env bash
# Issue 70, "a reward head that sees rare successes": the sparse push recipe of ../v3_5demos_100k_7b652a9 (5
# demonstrations, the same flags) with a class-balanced reward head (loss.reward_balance=1: the batch's successes weigh as
# much in total as its zeros). Three seeds in one run, 100,000 simulator steps from the start (the run it pairs with was a
# 60k run continued to 100k, so its demonstration share fell 50% -> 25% over 60k, here over 100k). Run from a worktree at
# commit 8de5a31 (git worktree add ../wt_8de5a31 8de5a31); 17,308 s for the three seeds together on the 2-core CPU,
# killed and resumed from its checkpoints by the same command.
python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 --workdir=runs/push_balance \
  --config.train.num_seeds=3 --config.online.reward=sparse --config.online.demos=5 --config.online.env_steps=100000 \
  --config.online.eval_every=20000 --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --config.loss.reward_balance=1
# The records here: python -m experiments.report records --workdir=runs/push_balance --out=results/sparse_push/balance_100k_8de5a31
# Paired against the run without balancing (the same held-out episodes; its policies tagged #balance):
R=results/sparse_push; for s in 0 1 2; do F+=" $R/v3_5demos_100k_7b652a9/seed${s}_episodes.csv.gz+$R/balance_100k_8de5a31/seed${s}_episodes.csv.gz#balance"; done
python -m experiments.report $F
# The reward head's calibration on held-out successes (the actor prior acting; results/reward_calibration/):
python -m experiments.diagnose reward --workdir=runs/push_balance/seed0 --workdir=runs/push_balance/seed1 \
  --workdir=runs/push_balance/seed2 --episodes=50 --out=push_balance_actor.json
