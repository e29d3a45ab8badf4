#!/usr/bin/env bash
# Issue 70, a Meta-World task the issue does not name, with only the task changed: sparse pick-place-v3, 5
# demonstrations, the recipe of sparse door-open and push (docs/sparse.md), three seeds in one run, 30k simulator
# steps (= 15k TD-MPC2 decisions). Run from a worktree at commit 3b9bf74 (3,910 s of acting and training for the
# three seeds together on the 2-core CPU, then the final evaluation, about 12 min). Then these records:
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 3b9bf74
python -m experiments.train --config=door_open_online.py:cpu --config.task=pick-place-v3 \
  --workdir=runs/sparse_pick_demos --config.train.num_seeds=3 --config.online.reward=sparse \
  --config.online.demos=5 --config.online.env_steps=30000 --config.online.eval_every=10000 \
  --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000
python -m experiments.report records --workdir=runs/sparse_pick_demos --out=results/sparse_pick_place/v3_5demos_3b9bf74
# BC on each seed's 5 demonstrations, the same held-out episodes (../bc_5demos/), and the pairing (pooled_with_bc.md):
for s in 0 1 2; do
  python -m experiments.evaluate bc --run=runs/sparse_pick_demos/seed$s --out=bc_seed$s.json
  gzip -9nc bc_seed$s.json > results/sparse_pick_place/bc_5demos/seed$s.json.gz
done
R=results/sparse_pick_place/v3_5demos_3b9bf74; B=results/sparse_pick_place/bc_5demos
python -m experiments.report $R/seed0_episodes.csv.gz+$B/seed0.json.gz $R/seed1_episodes.csv.gz+$B/seed1.json.gz \
  $R/seed2_episodes.csv.gz+$B/seed2.json.gz > $R/pooled_with_bc.md
# Paired with the dense pick-place run from scratch at 100k on the same held-out episodes (paired_with_dense.md):
D=results/online_pick/dense_3seeds_227620e
python -m experiments.report $R/seed0_episodes.csv.gz+$D/seed0_episodes.csv.gz#dense \
  $R/seed1_episodes.csv.gz+$D/seed1_episodes.csv.gz#dense $R/seed2_episodes.csv.gz+$D/seed2_episodes.csv.gz#dense > $R/paired_with_dense.md
# The curves (docs/pick_dense_sparse_curves.png) are drawn from the run continued to 60k: ../v3_5demos_60k_3b9bf74/run.sh
