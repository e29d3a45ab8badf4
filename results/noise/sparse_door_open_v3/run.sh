#!/usr/bin/env bash
# Run from a worktree of commit ec36f77 ($REPO); RUN: the workdir of the sparse door-open v3 run (commit 22ad14c, results/sparse_door_open/v3_bc_actor_safe_22ad14c/).
# Observation-noise sweep of the sparse door-open v3 checkpoints (3 training seeds, online :cpu, raw observations):
# planner, actor prior, proposal at std 0, 0.01, 0.02, 0.05 on the same held-out episodes; BC on each run's
# demonstrations under the same noise; then the planner's latent filter (f = 0.5) at evaluation only.
set -e
cd $REPO
R=RUN
O=OUT
for s in 0 1 2; do
  .venv/bin/python -m experiments.evaluate --workdir=$R/seed$s --seeds=0 --modes=plan,actor,proposal --splits=held_out \
    --noise_sweep --set=eval.noise_stds=0,0.01,0.02,0.05 --out=$O/seed$s.json --overwrite
done
for s in 0 1 2; do
  .venv/bin/python -m experiments.bc_baseline --run=$R/seed$s --noise_stds=0.01,0.02,0.05 --out=$O/bc_seed$s.json > $O/bc_seed$s.log 2>&1
done
for s in 0 1 2; do
  .venv/bin/python -m experiments.evaluate --workdir=$R/seed$s --seeds=0 --modes=plan,actor --splits=held_out \
    --noise_sweep --set=eval.noise_stds=0,0.01,0.02,0.05 --set=plan.latent_filter=0.5 --out=$O/filter_seed$s.json --overwrite
done
echo done
