#!/usr/bin/env bash
# Online from scratch, dense reward, push-v3, the :cpu preset (was :cpu_tanh), only the task changed, three training seeds
# (0, 1, 2) in one run, 100k simulator steps (= TD-MPC2's 50k decisions): the re-measure of the README row whose records
# were lost. Run from a worktree at commit fc00832 (git worktree add ../wt_fc00832 fc00832), interrupted and resumed from
# its checkpoints (the same command), mostly beside another run. Then these records: seed*/episodes.csv, eval.csv,
# online.csv, pooled.*.
python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 --workdir=runs/dense_push_3seeds \
  --config.train.num_seeds=3
# Pooled table and paired tests from the committed records:
python -m experiments.report results/online_push/dense_3seeds_fc00832/seed{0,1,2}_episodes.csv.gz
