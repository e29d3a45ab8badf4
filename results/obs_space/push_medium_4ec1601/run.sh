#!/usr/bin/env bash
# Issue 105: push-v3 `medium` (held-out goals), the offline door_open.py:cpu setting, three training seeds in one process,
# planning in the learned latent space (latent/) and in OBSERVATION space (obs/: model.encoder_type=identity, z = the
# standardised 39-d observation), both trained side by side from one worktree of commit 4ec1601 ($REPO), 2026-12-07, on a
# 2-core AMD EPYC (about 100 min of training each with the other beside it). Rerunning resumes from the newest checkpoints.
# The paired comparison on the same held-out episodes:
#   R=results/obs_space/push_medium_4ec1601
#   python -m experiments.report $R/latent/seed0_episodes.csv.gz+$R/obs/seed0_episodes.csv.gz#obs \
#     $R/latent/seed1_episodes.csv.gz+$R/obs/seed1_episodes.csv.gz#obs $R/latent/seed2_episodes.csv.gz+$R/obs/seed2_episodes.csv.gz#obs
# Records: python -m experiments.report records --workdir=runs/obs_push/latent --out=$R/latent (and obs/ the same way).
set -e
cd "$REPO"  # a worktree of commit 4ec1601
R=runs/obs_push
COMMON="--config=door_open.py:cpu --config.task=push-v3 --config.train.num_seeds=3 --config.data.preset=medium --config.eval.splits=held_out"
.venv/bin/python -m experiments.train $COMMON --workdir=$R/latent &
# The first collects push `medium` into data_cache/ (written whole, then renamed); the second reads it.
until ls data_cache/push-v3_medium_200ep_seed0_ar2*.npz >/dev/null 2>&1; do sleep 10; done
.venv/bin/python -m experiments.train $COMMON --workdir=$R/obs \
  --config.model.encoder_type=identity --config.model.latent_dim=39 --config.model.normalize_dynamics=False &
wait
