#!/usr/bin/env bash
# Issue 71: the offline door_open.py:cpu setting (medium data, held-out goals) retrained with the constant-feature mask
# (model.obs_mask_constant, the default since it landed), three training seeds in one process (one virtual CPU device
# each), then each seed's noise sweep: planner, actor prior, proposal at std 0, 0.01, 0.02, 0.05 on the same held-out
# episodes; then BC (data seed 0) on the same episodes under the same noise. Run from a worktree of commit 859bac5 ($REPO); resumes where it stopped.
# Here: the final evaluation (seed*_episodes.csv.gz, pooled.*), each seed's sweep (seed*.json.gz) and BC's (bc.json.gz).
# Table and plot: python -m experiments.report --noise_plot=docs/noise_offline_door_open.png R/seed{0,1,2}.json.gz
set -e
cd "$REPO"  # a worktree of commit 859bac5
R=runs/noise_offline_mask/run
O=runs/noise_offline_mask
if [ ! -f $R/pooled.json ]; then
  .venv/bin/python -m experiments.train --config=door_open.py:cpu --workdir=$R --config.train.num_seeds=3 \
    --config.data.preset=medium --config.eval.splits=held_out
fi
for s in 0 1 2; do
  [ -f $O/seed$s.json ] || .venv/bin/python -m experiments.evaluate --workdir=$R/seed$s --seeds=0 \
    --modes=plan,actor,proposal --splits=held_out --noise_sweep --config.eval.noise_stds=0,0.01,0.02,0.05 --out=$O/seed$s.json
done
# BC on the same medium data (data seed 0) and the same held-out episodes (evaluation seed 0, which every seed's sweep uses)
[ -f $O/bc.json ] || .venv/bin/python -m experiments.evaluate bc --task=door-open-v3 --preset=medium --seed=0 \
  --noise_stds=0.01,0.02,0.05 --out=$O/bc.json > $O/bc.log 2>&1
echo done
