#!/usr/bin/env bash
# The sparse pick-place run of ../v3_5demos_3b9bf74/ (same workdir) continued from its 30,400 checkpoint to 60k
# simulator steps (= 30k TD-MPC2 decisions); only online.env_steps changed (--continue_with_changes keeps
# config.1.json; the annealed schedules stretch to 60k, as push's 60k -> 100k did). Worktree at commit 3b9bf74.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 3b9bf74
python -m experiments.train --config=door_open_online.py:cpu --config.task=pick-place-v3 \
  --workdir=runs/sparse_pick_demos --config.train.num_seeds=3 --config.online.reward=sparse \
  --config.online.demos=5 --config.online.env_steps=60000 --config.online.eval_every=10000 \
  --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000 --continue_with_changes
python -m experiments.report records --workdir=runs/sparse_pick_demos --out=results/sparse_pick_place/v3_5demos_60k_3b9bf74
R=results/sparse_pick_place/v3_5demos_60k_3b9bf74; R30=results/sparse_pick_place/v3_5demos_3b9bf74
B=results/sparse_pick_place/bc_5demos; D=results/online_pick/dense_3seeds_227620e
# Paired with the same run at 30k (policies #30k) and BC on the same demonstrations, on the same held-out episodes:
python -m experiments.report $R/seed0_episodes.csv.gz+$R30/seed0_episodes.csv.gz#30k+$B/seed0.json.gz \
  $R/seed1_episodes.csv.gz+$R30/seed1_episodes.csv.gz#30k+$B/seed1.json.gz \
  $R/seed2_episodes.csv.gz+$R30/seed2_episodes.csv.gz#30k+$B/seed2.json.gz > $R/paired_with_30k_bc.md
# Paired with the dense pick-place run from scratch at 100k (paired_with_dense.md):
python -m experiments.report $R/seed0_episodes.csv.gz+$D/seed0_episodes.csv.gz#dense \
  $R/seed1_episodes.csv.gz+$D/seed1_episodes.csv.gz#dense $R/seed2_episodes.csv.gz+$D/seed2_episodes.csv.gz#dense > $R/paired_with_dense.md
# Curves, dense from scratch and sparse with 5 demonstrations, against TD-MPC2's published dense seeds (decisions doubled):
python -m experiments.report curves --workdir=$D/seed0_,$D/seed1_,$D/seed2_,$R/seed0_,$R/seed1_,$R/seed2_ \
  --anchor=docs/anchors/tdmpc2_mw-pick-place.csv --max_steps=200000 --out=docs/pick_dense_sparse_curves.png
