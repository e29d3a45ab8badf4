#!/usr/bin/env bash
# Issue 100, item 4: the same-budget TD-MPC2 control (door_open_online.py:tdmpc2_cpu; its recipe from this library's kinds at
# :cpu's width, batch, updates per step, environments and rollouts per decision), dense door-open from scratch, three training
# seeds in one run, to 200k simulator steps (= TD-MPC2's 100k decisions). Run from a worktree at commit 08c4c03
# (git worktree add ../wt_08c4c03 08c4c03), nice 19 beside other work, stopped by session ends and resumed from its
# checkpoints (every 4,000 steps; rerunning the command resumes). Then these records:
#   python -m experiments.report records --workdir=RUNDIR --out=THIS_FOLDER
python -m experiments.train --config=door_open_online.py:tdmpc2_cpu --workdir=runs/tdmpc2_door200k/run \
  --config.train.num_seeds=3 --config.online.env_steps=200000
# Pooled table:
python -m experiments.report results/online_door/tdmpc2_200k_3seeds_08c4c03/seed{0,1,2}_episodes.csv.gz
# Paired with LD-MPC (:cpu, the same 50 held-out episodes per seed, results/online_door/dense200k_3seeds_7d733ad):
A=results/online_door/dense200k_3seeds_7d733ad; B=results/online_door/tdmpc2_200k_3seeds_08c4c03
python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#tdmpc2 \
  $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#tdmpc2 $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#tdmpc2
