#!/usr/bin/env bash
# Issue 105: door-open medium from pixels (door_open.py:cpu_pixels: 48 x 48 RGB, one frame, the conv encoder, batch 64),
# three training seeds in one process, held-out goals; planner, actor prior and proposal alone on 50 episodes each.
# Run from a worktree of commit df97d0a ($REPO); rerunning resumes from the newest checkpoint. On the 2-core AMD EPYC, alone:
# about 10 min of rendering the 200 episodes, 5,720 s of training, 12 min of evaluation a seed. The paired comparison with
# the state agent (same held-out episodes):
#   A=results/noise/offline_door_medium_mask_859bac5; B=results/pixels/door_medium_df97d0a
#   python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#pixels \
#     $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#pixels $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#pixels
set -e
cd "$REPO"  # a worktree of commit df97d0a
export MUJOCO_GL=osmesa
.venv/bin/python -m experiments.train --config=door_open.py:cpu_pixels --workdir=runs/pixels_door_medium/run \
  --config.train.num_seeds=3 --config.data.preset=medium --config.eval.splits=held_out
