#!/usr/bin/env bash
# Online from scratch, dense reward, push-v3, the :cpu preset (no latent rollout) with only the task changed, three
# training seeds (0, 1, 2) in one run, to 200k simulator steps (= TD-MPC2's 100k decisions, the step count it publishes
# at). Run from a worktree at commit 18a5220 (git worktree add ../wt_18a5220 18a5220), nice 19 beside other work, resumed
# once from its checkpoints (every 4,000 steps; rerunning the command resumes); 12,770 s of acting and training for the
# three seeds together. Then these records: python -m experiments.report records --workdir=RUNDIR --out=THIS_FOLDER
cd "$(git rev-parse --show-toplevel)"
python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 --workdir=runs/push200k/run \
  --config.train.num_seeds=3 --config.online.env_steps=200000
# Pooled table and paired tests from the committed records: planner 141/150 (48, 45, 48), actor prior 136/150 (12 / 7,
# p = 0.36), proposal alone 48/150.
python -m experiments.report results/online_push/dense200k_3seeds_18a5220/seed{0,1,2}_episodes.csv.gz
# Against the 100k run of the same preset on the same held-out episodes (results/online_push/norollout_3seeds_45fd6aa,
# 53/150): 3 / 91, p = 1.4e-23.
A=results/online_push/norollout_3seeds_45fd6aa; B=results/online_push/dense200k_3seeds_18a5220
python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#at200k \
  $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#at200k $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#at200k
# Curves beside TD-MPC2 (docs/dense_push_curves.png), from these records:
python -m experiments.report curves --workdir=$B/seed0_ --workdir=$B/seed1_ --workdir=$B/seed2_ \
  --anchor=docs/anchors/tdmpc2_mw-push.csv --max_steps=200000 --out=docs/dense_push_curves.png
