#!/usr/bin/env bash
# Issue 100, item 3, second attempt (a probe on one seed): the proposal denoises the planner's chosen sequences where the
# planner acted (loss.act_target='planned'), dense door-open from scratch, :cpu, training seed 0 alone, 100k simulator
# steps. From a worktree at commit b229cd4 (git worktree add ../wt_b229cd4 b229cd4); 2,125 s of acting and training
# beside another run.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_plan_s0 \
  --config.seed=0 --config.loss.act_target=planned
python -m experiments.report records --workdir=runs/door_plan_s0 --out=results/online_door/plan_seed0_b229cd4
# Paired with seed 0 of the run without it (the same preset and steps, commit 83ada3e) on the same 50 held-out episodes:
python -m experiments.report \
  'results/online_door/dense_3seeds_83ada3e/seed0_episodes.csv.gz+results/online_door/plan_seed0_b229cd4/episodes.csv.gz#planned'
# Who won the acting decisions, per 40k simulator steps, with and without it:
python -m experiments.report acting results/online_door/plan_seed0_b229cd4/online.csv.gz \
  results/online_door/dense_3seeds_83ada3e/seed0_online.csv --every=40000
