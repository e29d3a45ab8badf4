#!/usr/bin/env bash
# Issue 105: door-open medium from one 48 x 48 RGB frame with the robot's state after it (door_open.py:cpu_pixels with
# model.proprio), three training seeds in one process, held-out goals: the run of results/pixels/door_medium_proprio8k_6d966fe
# (its two commands: 4,000 then 8,000 updates, from a worktree of commit 6d966fe) trained on to 12,000 updates by the first
# command below, from a worktree of commit 318d80b ($REPO) with the 8,000-update run directory copied in (the learning rate
# is constant after warm-up and resuming is exact, so this is the 12,000-update run). On the 2-core AMD EPYC: 83 min for the
# last 4,000 updates of the three seeds (14,494 s of training in all, 81 min a seed), then the run's own final evaluation
# (planner and actor prior, 50 held-out episodes a seed; 12 min beside the second command).
# From scratch in one command: the first command of door_medium_proprio8k_6d966fe/run.sh with --config.train.num_steps=12000
# --config.train.eval_every=12000 (not run that way here: this run was resumed twice, which is exact; the code between
# 6d966fe and 318d80b changed nothing it computes).
# The planner with safe selection on the same checkpoints and episodes (seed<s>_safe.json.gz, gzipped), from main at
# commit 31c5635, the second command.
# The paired comparisons on the same held-out episodes, against the state agent (A) and this run at 8,000 updates (D):
#   A=results/noise/offline_door_medium_mask_859bac5; D=results/pixels/door_medium_proprio8k_6d966fe; E=results/pixels/door_medium_proprio12k_318d80b
#   python -m experiments.report $A/seed0_episodes.csv.gz+$D/seed0_episodes.csv.gz#8k+$E/seed0_episodes.csv.gz#12k+$E/seed0_safe.json.gz#safe12k \
#     $A/seed1_episodes.csv.gz+$D/seed1_episodes.csv.gz#8k+$E/seed1_episodes.csv.gz#12k+$E/seed1_safe.json.gz#safe12k \
#     $A/seed2_episodes.csv.gz+$D/seed2_episodes.csv.gz#8k+$E/seed2_episodes.csv.gz#12k+$E/seed2_safe.json.gz#safe12k
set -e
cd "$REPO"  # a worktree of commit 318d80b, holding the run directory of door_medium_proprio8k_6d966fe/run.sh
export MUJOCO_GL=osmesa
.venv/bin/python -m experiments.train --config=door_open.py:cpu_pixels --workdir=runs/pixels_proprio8k_door_medium/run \
  --config.model.proprio=True --config.obs_dim=6920 --config.train.num_seeds=3 --config.data.preset=medium \
  --config.eval.splits=held_out --config.eval.baselines=actor --config.train.eval_every=12000 \
  --config.train.num_steps=12000 --continue_with_changes
for s in 0 1 2; do  # from main at commit 31c5635
  .venv/bin/python -m experiments.evaluate --workdir=runs/pixels_proprio8k_door_medium/run/seed$s --modes=plan \
    --splits=held_out --config.plan.safe_selection=True --out=runs/pixels_proprio8k_door_medium/seed${s}_safe.json
done
