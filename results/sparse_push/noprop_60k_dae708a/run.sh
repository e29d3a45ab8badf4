#!/usr/bin/env bash
# Issue 70, "does the diffusion proposal explore?" on push, where its candidates won 19-26% of acting decisions (to 60k; 26-34% over 100k): the sparse
# push recipe of ../v3_5demos_7b652a9 (5 demonstrations, the same flags, 60k simulator steps = 30k TD-MPC2 decisions) with
# the proposal's candidates removed while acting (online.act_proposal=False; evaluation keeps them). Three seeds in one run.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit dae708a
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 \
  --workdir=runs/sparse_push_noprop --config.train.num_seeds=3 --config.online.reward=sparse \
  --config.online.demos=5 --config.online.env_steps=60000 --config.online.eval_every=20000 \
  --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --config.online.act_proposal=False
# Paired with the run with the proposal at 60k, on the same held-out episodes (this run's policies tagged #noprop):
B=results/sparse_push/v3_5demos_7b652a9; N=results/sparse_push/noprop_60k_dae708a
python -m experiments.report $B/seed0_episodes.csv.gz+$N/seed0_episodes.csv.gz#noprop \
  $B/seed1_episodes.csv.gz+$N/seed1_episodes.csv.gz#noprop $B/seed2_episodes.csv.gz+$N/seed2_episodes.csv.gz#noprop
