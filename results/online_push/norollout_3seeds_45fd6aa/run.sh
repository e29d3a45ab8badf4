#!/usr/bin/env bash
# Issue 101: the :cpu preset without the latent rollout in the update (--config.critic.latent_rollout=False), dense push-v3
# from scratch, three training seeds in one run, 100k simulator steps, to pair with results/online_push/dense_3seeds_fc00832
# (the same held-out episodes). Worktree at commit 45fd6aa (the door run's, results/online_door/norollout_3seeds_45fd6aa),
# alone on the 2-core CPU (5,428 s). Rerunning the command resumes from the newest checkpoint.
python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 --workdir=runs/push_norollout3 \
  --config.train.num_seeds=3 --config.critic.latent_rollout=False
python -m experiments.report records --workdir=runs/push_norollout3 --out=results/online_push/norollout_3seeds_45fd6aa
# Result: planner 53/150 (33, 12, 8), actor 56/150, proposal 18/150; against :cpu with the rollout (fc00832) on the same
# episodes 53 vs 56 (22 / 25, p = 0.77), level; its seed 1 (2/50 there) learns (12/50):
#   A=results/online_push/dense_3seeds_fc00832; B=results/online_push/norollout_3seeds_45fd6aa
#   python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#norollout $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#norollout $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#norollout
