#!/usr/bin/env bash
# Issue 105: door-open medium from one 48 x 48 RGB frame with the robot's state after it (door_open.py:cpu_pixels with
# model.proprio, MoDem's observation without a frame stack), three training seeds in one process, held-out goals.
# Run from a worktree of commit 6d966fe ($REPO). On the 2-core AMD EPYC: rendering about 8 min, training 86 min for the
# three seeds. The run's own final evaluation was stopped (the machine ran out of memory evaluating the seeds in parallel
# processes); the planner was evaluated one seed at a time with the second command, on the run's 50 held-out episodes a
# seed (the actor prior not evaluated). The paired comparison with the state agent and the one-frame run without the
# robot's state (same held-out episodes):
#   A=results/noise/offline_door_medium_mask_859bac5; B=results/pixels/door_medium_df97d0a; C=results/pixels/door_medium_proprio_6d966fe
#   python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#pixels+$C/seed0_plan.json.gz#proprio \
#     $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#pixels+$C/seed1_plan.json.gz#proprio \
#     $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#pixels+$C/seed2_plan.json.gz#proprio
set -e
cd "$REPO"  # a worktree of commit 6d966fe
export MUJOCO_GL=osmesa
.venv/bin/python -m experiments.train --config=door_open.py:cpu_pixels --workdir=runs/pixels_proprio_door_medium/run \
  --config.model.proprio=True --config.obs_dim=6920 --config.train.num_seeds=3 --config.data.preset=medium \
  --config.eval.splits=held_out --config.eval.baselines=actor --config.train.eval_every=4000
for s in 0 1 2; do
  .venv/bin/python -m experiments.evaluate --workdir=runs/pixels_proprio_door_medium/run/seed$s --modes=plan \
    --splits=held_out --out=runs/pixels_proprio_door_medium/run/seed$s/final_plan.json
done
