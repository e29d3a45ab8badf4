#!/usr/bin/env bash
# Online from scratch, dense reward, door-open-v3, the :cpu preset (was :cpu_tanh), three training seeds (0, 1, 2) in one
# run, 100k simulator steps (= TD-MPC2's 50k decisions): the re-measure of the README row whose records were lost.
# Run from a worktree at commit 83ada3e (git worktree add ../wt_83ada3e 83ada3e); 16,465 s for the three seeds together,
# beside another run for part of the time. Then these records: seed*/episodes.csv, eval.csv, online.csv, pooled.*.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/dense_door_3seeds --config.train.num_seeds=3
# Pooled table and paired tests from the committed records:
python -m experiments.report results/online_door/dense_3seeds_83ada3e/seed{0,1,2}_episodes.csv.gz
