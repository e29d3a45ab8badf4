#!/usr/bin/env bash
# Online from scratch, dense reward, peg-insert-side-v3, the :cpu preset (no latent rollout) with only the task changed,
# three training seeds (0, 1, 2) in one run, to 200k simulator steps (= TD-MPC2's 100k decisions, the step count it
# publishes at). Run from a worktree at commit 18a5220 (git worktree add ../wt_18a5220 18a5220), nice 19 beside other
# work, resumed twice from its checkpoints (every 4,000 steps; rerunning the command resumes); 11,361 s of acting and
# training for the three seeds together (seed0_report.md). Then these records:
# python -m experiments.report records --workdir=RUNDIR --out=THIS_FOLDER
cd "$(git rev-parse --show-toplevel)"
python -m experiments.train --config=door_open_online.py:cpu --config.task=peg-insert-side-v3 --workdir=runs/peg200k/run \
  --config.train.num_seeds=3 --config.online.env_steps=200000
# Pooled table and paired tests from the committed records: planner 106/150 (50, 48, 8), actor prior 108/150 (6 / 8,
# p = 0.79), proposal alone 34/150.
python -m experiments.report results/online_peg/dense200k_3seeds_18a5220/seed{0,1,2}_episodes.csv.gz
# Against the 100k run on the same held-out episodes (results/online_peg/dense_3seeds_3d9a61f, 14/150; that run's :cpu
# still trained with the latent rollout, so two things changed): 0 / 92, p = 4.0e-28.
A=results/online_peg/dense_3seeds_3d9a61f; B=results/online_peg/dense200k_3seeds_18a5220
python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#at200k \
  $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#at200k $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#at200k
# Curves beside TD-MPC2 (docs/dense_peg_curves.png), from these records:
python -m experiments.report curves --workdir=$B/seed0_ --workdir=$B/seed1_ --workdir=$B/seed2_ \
  --anchor=docs/anchors/tdmpc2_mw-peg-insert-side.csv --max_steps=200000 --out=docs/dense_peg_curves.png
