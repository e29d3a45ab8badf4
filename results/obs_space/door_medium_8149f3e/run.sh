#!/usr/bin/env bash
# Issue 105: the offline door_open.py:cpu setting on door-open medium data (held-out goals), three training seeds in one
# process, planning in OBSERVATION space (model.encoder_type=identity: z = the standardised 39-d observation); otherwise the
# training command of results/noise/offline_door_medium_mask_859bac5/run.sh. Run from a worktree of commit 8149f3e ($REPO);
# rerunning resumes from the newest checkpoint. The paired comparison with the latent planner (same held-out episodes):
#   A=results/noise/offline_door_medium_mask_859bac5; B=results/obs_space/door_medium_8149f3e
#   python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#obs \
#     $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#obs $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#obs
set -e
cd "$REPO"  # a worktree of commit 8149f3e
.venv/bin/python -m experiments.train --config=door_open.py:cpu --workdir=runs/obs_door_medium/run \
  --config.train.num_seeds=3 --config.data.preset=medium --config.eval.splits=held_out \
  --config.model.encoder_type=identity --config.model.latent_dim=39 --config.model.normalize_dynamics=False
