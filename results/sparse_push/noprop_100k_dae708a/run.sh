#!/usr/bin/env bash
# Issue 70, "does the diffusion proposal explore?" on push: the run of ../noprop_60k_dae708a/run.sh (same workdir, the
# proposal's candidates removed while acting) continued from its 60k checkpoint to 100k simulator steps (= 50k TD-MPC2
# decisions), as the run it pairs with (../v3_5demos_100k_7b652a9) was; only online.env_steps changed.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit dae708a
exec .venv/bin/python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 \
  --workdir=runs/sparse_push_noprop --config.train.num_seeds=3 --config.online.reward=sparse \
  --config.online.demos=5 --config.online.env_steps=100000 --config.online.eval_every=20000 \
  --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --config.online.act_proposal=False --continue_with_changes
# Paired with the run with the proposal at 100k, on the same held-out episodes (this run's policies tagged #noprop):
B=results/sparse_push/v3_5demos_100k_7b652a9; N=results/sparse_push/noprop_100k_dae708a
python -m experiments.report $B/seed0_episodes.csv.gz+$N/seed0_episodes.csv.gz#noprop \
  $B/seed1_episodes.csv.gz+$N/seed1_episodes.csv.gz#noprop $B/seed2_episodes.csv.gz+$N/seed2_episodes.csv.gz#noprop
