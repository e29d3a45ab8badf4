#!/usr/bin/env bash
# Issue 105: door-open medium from one 48 x 48 RGB frame with the robot's state after it (door_open.py:cpu_pixels with
# model.proprio), three training seeds in one process, held-out goals: the run of results/pixels/door_medium_proprio_6d966fe
# (4,000 updates, its first command) trained on to 8,000 updates (the second: the same config but num_steps and eval_every,
# resumed from its 4,000-update checkpoints; the learning rate is constant after warm-up and resuming is exact, so this is
# the 8,000-update run). Run from a worktree of commit 6d966fe ($REPO). On the 2-core AMD EPYC: 86 + 80 min of training
# for the three seeds, then the run's own final evaluation (planner and actor prior, 50 held-out episodes a seed); it was
# stopped at seed 2 (the process held 23.4 GB: each seed's evaluation environments, with a renderer each, stayed), and the
# same command again evaluated seed 2 (seeds 0 and 1 from their saved reports).
# The planner with safe selection on the same checkpoints and episodes (seed<s>_safe.json.gz, gzipped), from main at
# commit 7a79f0e (the same frames: the shared renderer draws what each environment's own did), the third command.
# The paired comparisons on the same held-out episodes, against the state agent (A) and this run at 4,000 updates (C):
#   A=results/noise/offline_door_medium_mask_859bac5; C=results/pixels/door_medium_proprio_6d966fe; D=results/pixels/door_medium_proprio8k_6d966fe
#   python -m experiments.report $A/seed0_episodes.csv.gz+$C/seed0_plan.json.gz#4k+$D/seed0_episodes.csv.gz#8k+$D/seed0_safe.json.gz#safe8k \
#     $A/seed1_episodes.csv.gz+$C/seed1_plan.json.gz#4k+$D/seed1_episodes.csv.gz#8k+$D/seed1_safe.json.gz#safe8k \
#     $A/seed2_episodes.csv.gz+$C/seed2_plan.json.gz#4k+$D/seed2_episodes.csv.gz#8k+$D/seed2_safe.json.gz#safe8k
set -e
cd "$REPO"  # a worktree of commit 6d966fe
export MUJOCO_GL=osmesa
.venv/bin/python -m experiments.train --config=door_open.py:cpu_pixels --workdir=runs/pixels_proprio8k_door_medium/run \
  --config.model.proprio=True --config.obs_dim=6920 --config.train.num_seeds=3 --config.data.preset=medium \
  --config.eval.splits=held_out --config.eval.baselines=actor --config.train.eval_every=4000
.venv/bin/python -m experiments.train --config=door_open.py:cpu_pixels --workdir=runs/pixels_proprio8k_door_medium/run \
  --config.model.proprio=True --config.obs_dim=6920 --config.train.num_seeds=3 --config.data.preset=medium \
  --config.eval.splits=held_out --config.eval.baselines=actor --config.train.eval_every=8000 \
  --config.train.num_steps=8000 --continue_with_changes
for s in 0 1 2; do  # from main at commit 7a79f0e
  .venv/bin/python -m experiments.evaluate --workdir=runs/pixels_proprio8k_door_medium/run/seed$s --modes=plan \
    --splits=held_out --config.plan.safe_selection=True --out=runs/pixels_proprio8k_door_medium/seed${s}_safe.json
done
