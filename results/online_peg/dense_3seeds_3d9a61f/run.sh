#!/usr/bin/env bash
# Issue 74, breadth: online from scratch, dense reward, peg-insert-side-v3, the :cpu preset with only the task changed,
# three training seeds (0, 1, 2) in one run, 100k simulator steps (= TD-MPC2's 50k decisions), 50 held-out episodes per
# seed at the end. Run from a worktree at commit 3d9a61f; 6,244 s for the three seeds together, alone on the 2-core CPU
# (beside short test runs). Then these records: seed*/episodes.csv, eval.csv, online.csv, pooled.*.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 3d9a61f
python -m experiments.train --config=door_open_online.py:cpu --config.task=peg-insert-side-v3 \
  --workdir=runs/dense_peg_3seeds --config.train.num_seeds=3
# Pooled table and paired tests from the committed records:
python -m experiments.report results/online_peg/dense_3seeds_3d9a61f/seed{0,1,2}_episodes.csv.gz
