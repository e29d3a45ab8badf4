#!/usr/bin/env bash
# Issue 74, breadth: online from scratch, dense reward, pick-place-v3, the :cpu preset with only the task changed,
# three training seeds (0, 1, 2) in one run, 100k simulator steps (= TD-MPC2's 50k decisions), 50 held-out episodes per
# seed at the end. Run from a worktree at commit 227620e over two sessions (killed at a session's end after its 64k
# checkpoint, resumed by the same command); 7-10 simulator steps/s per seed on the 2-core CPU (slow days), 13,782 s
# of acting and training for the three seeds together (pooled.md). Then these records:
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 227620e
python -m experiments.train --config=door_open_online.py:cpu --config.task=pick-place-v3 \
  --workdir=runs/dense_pick_3seeds --config.train.num_seeds=3
python -m experiments.report records --workdir=runs/dense_pick_3seeds --out=results/online_pick/dense_3seeds_227620e
# Pooled table and paired tests from the committed records:
python -m experiments.report results/online_pick/dense_3seeds_227620e/seed{0,1,2}_episodes.csv.gz
# The curves against TD-MPC2's published seeds (its decisions doubled):
R=results/online_pick/dense_3seeds_227620e
python -m experiments.report curves --workdir=$R/seed0_,$R/seed1_,$R/seed2_ \
  --anchor=docs/anchors/tdmpc2_mw-pick-place.csv --max_steps=200000 --out=docs/dense_pick_curves.png
