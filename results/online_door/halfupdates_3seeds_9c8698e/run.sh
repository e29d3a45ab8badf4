#!/usr/bin/env bash
# Issue 101: half the updates per simulator step (online.update_ratio=0.25, batch 128 unchanged; :cpu has 0.5 = TD-MPC2's one
# per decision), dense door-open from scratch, :cpu, three training seeds in one run, 100k simulator steps. From a worktree
# at commit 9c8698e (git worktree add ../wt_9c8698e 9c8698e); 2,808 s of acting and training for the three seeds together
# (107 simulator steps/s in all, beside a niced run), against 16,465 s for the run it is paired with (beside another run).
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_ur025 \
  --config.train.num_seeds=3 --config.online.update_ratio=0.25
python -m experiments.report records --workdir=runs/door_ur025 --out=results/online_door/halfupdates_3seeds_9c8698e
# Paired with the :cpu run (update_ratio 0.5, commit 83ada3e) on the same 50 held-out episodes a seed:
python -m experiments.report $(for s in 0 1 2; do echo "results/online_door/dense_3seeds_83ada3e/seed${s}_episodes.csv.gz+results/online_door/halfupdates_3seeds_9c8698e/seed${s}_episodes.csv.gz#half"; done)
