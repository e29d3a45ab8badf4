#!/usr/bin/env bash
# Issue 100, item 3, first attempt (a probe on one seed): the proposal's denoising loss weighted by the critics' AWR
# weight of each window's first action (loss.act_weighting='advantage'), dense door-open from scratch, :cpu, training
# seed 0 alone, 100k simulator steps. From a worktree at commit acd8528 (git worktree add ../wt_acd8528 acd8528);
# 3,040 s of acting and training beside other work.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_actw_s0 \
  --config.seed=0 --config.loss.act_weighting=advantage
python -m experiments.report records --workdir=runs/door_actw_s0 --out=results/online_door/actw_seed0_acd8528
# Paired with seed 0 of the run without it (the same preset and steps, commit 83ada3e) on the same 50 held-out episodes:
python -m experiments.report \
  'results/online_door/dense_3seeds_83ada3e/seed0_episodes.csv.gz+results/online_door/actw_seed0_acd8528/episodes.csv.gz#actw'
