#!/usr/bin/env bash
# Issue 71: noise augmentation measured on its own. The offline door_open.py:cpu setting of
# ../offline_door_medium_mask_859bac5 (medium data, held-out goals, the constant-feature mask) retrained with
# train.obs_noise_aug=0.01 (the models see enc(o + noise); consistency and value targets from the clean observations),
# three training seeds in one process, then each seed's noise sweep on the same held-out episodes. Run from a worktree of
# commit 859bac5 ($REPO); 2,673 s of training. Here: the final evaluation (seed*_episodes.csv.gz, pooled.*) and the sweeps.
set -e
cd "$REPO"
R=runs/noise_offline_aug/run
O=runs/noise_offline_aug
python -m experiments.train --config=door_open.py:cpu --workdir=$R --config.train.num_seeds=3 \
  --config.data.preset=medium --config.eval.splits=held_out --config.train.obs_noise_aug=0.01
for s in 0 1 2; do
  python -m experiments.evaluate --workdir=$R/seed$s --seeds=0 --modes=plan,actor,proposal --splits=held_out \
    --noise_sweep --config.eval.noise_stds=0,0.01,0.02,0.05 --out=$O/seed$s.json
done
# Paired against the mask-only checkpoints (their policies plain, these tagged #aug):
M=results/noise/offline_door_medium_mask_859bac5; A=results/noise/offline_door_medium_aug_859bac5
python -m experiments.report --noise_plot=aug.png $M/seed0.json.gz+$A/seed0.json.gz#aug $M/seed1.json.gz+$A/seed1.json.gz#aug \
  $M/seed2.json.gz+$A/seed2.json.gz#aug
