#!/usr/bin/env bash
# Issue 70, the learned progress reward measured: sparse push-v3, 5 demonstrations, the recipe of ../v3_5demos_100k_7b652a9
# (the README's sparse push row) plus the progress head (loss.w_progress=1) and its shaping in J (plan.progress_weight=10:
# full progress worth half the value of a solved state, 1/(1-0.95) = 20; a guess, not tuned). Three seeds in one run,
# 100k simulator steps (= 50k TD-MPC2 decisions) in one go (the row it is paired with ran to 60k and was continued, so its
# demonstration share annealed 50% -> 25% over the first 60k; here over 100k). Stopped and resumed from its checkpoints across sessions.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 1005061
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 \
  --workdir=runs/sparse_push_progress --config.train.num_seeds=3 --config.online.reward=sparse \
  --config.online.demos=5 --config.online.env_steps=100000 --config.online.eval_every=20000 \
  --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 \
  --config.loss.w_progress=1.0 --config.plan.progress_weight=10.0
# Paired with the run without it, on the same held-out episodes (this run's policies tagged #prog):
B=results/sparse_push/v3_5demos_100k_7b652a9; P=results/sparse_push/progress_w10_1005061
python -m experiments.report $B/seed0_episodes.csv.gz+$P/seed0_episodes.csv.gz#prog \
  $B/seed1_episodes.csv.gz+$P/seed1_episodes.csv.gz#prog $B/seed2_episodes.csv.gz+$P/seed2_episodes.csv.gz#prog
