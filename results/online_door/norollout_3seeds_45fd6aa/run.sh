#!/usr/bin/env bash
# Issue 101: a cheaper update, the :cpu preset without the latent rollout in the update (--config.critic.latent_rollout=False:
# 37% of its FLOPs, results/benchmarks/update_split_cpu.md), dense door-open from scratch, three training seeds in one run,
# 100k simulator steps, to pair with results/online_door/dense_3seeds_83ada3e (the same held-out episodes). Worktree
# at commit 45fd6aa. Rerunning this script resumes from the newest checkpoint.
cd "$REPO"  # a worktree of commit 45fd6aa
. .venv/bin/activate
exec nice -n 10 python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_norollout3/run \
  --config.train.num_seeds=3 --config.critic.latent_rollout=False
# Result (3,729 s): planner 150/150, actor 149/150, proposal 126/150; against :cpu with the rollout (83ada3e) on the same episodes 150 vs 96 (54 / 0, p = 1.1e-16):
#   A=results/online_door/dense_3seeds_83ada3e; B=results/online_door/norollout_3seeds_45fd6aa
#   python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#norollout $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#norollout $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#norollout
