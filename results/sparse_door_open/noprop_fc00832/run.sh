#!/usr/bin/env bash
# Issue 70, "does the diffusion proposal explore?": the sparse door-open recipe of ../v3_bc_actor_safe_22ad14c (5
# demonstrations, the same flags) with the proposal's candidates removed while acting (online.act_proposal=False;
# evaluation keeps them). Three seeds in one run, 30,400 simulator steps. Run from a worktree at commit fc00832
# (git worktree add ../wt_fc00832 fc00832); 4,776 s for the three seeds together, beside another run.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/sparse_door_noprop \
  --config.train.num_seeds=3 --config.online.reward=sparse --config.online.demos=5 --config.online.env_steps=30000 \
  --config.online.eval_every=10000 --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --config.online.act_proposal=False
# Paired against the run with the proposal (the same held-out episodes; its policies tagged #noprop):
R=results/sparse_door_open; for s in 0 1 2; do F+=" $R/v3_bc_actor_safe_22ad14c/seed${s}_episodes.csv.gz+$R/noprop_fc00832/seed${s}_episodes.csv.gz#noprop"; done
python -m experiments.report $F
