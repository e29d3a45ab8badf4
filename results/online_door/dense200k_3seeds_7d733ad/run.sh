#!/usr/bin/env bash
# Online from scratch, dense reward, door-open-v3, the :cpu preset, three training seeds (0, 1, 2) in one run, to 200k
# simulator steps (= TD-MPC2's 100k decisions, the step count it publishes at; issue 100). Run from a worktree at commit
# 7d733ad (git worktree add ../wt_7d733ad 7d733ad), nice 19 beside other work, stopped by session ends and resumed 6 times
# from its checkpoints (every 4,000 steps; rerunning the command resumes); 21,645 s of acting and training for the
# three seeds together. Then these records: python -m experiments.report records --workdir=RUNDIR --out=THIS_FOLDER
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door200k/run \
  --config.train.num_seeds=3 --config.online.env_steps=200000
# Pooled table and paired tests from the committed records:
python -m experiments.report results/online_door/dense200k_3seeds_7d733ad/seed{0,1,2}_episodes.csv.gz
# Curves beside TD-MPC2 (docs/dense_door_curves.png; needs the run directory's eval.csv and online.csv per seed):
python -m experiments.report curves --workdir=runs/door200k/run/seed0 --workdir=runs/door200k/run/seed1 \
  --workdir=runs/door200k/run/seed2 --anchor=docs/anchors/tdmpc2_mw-door-open.csv --max_steps=200000 \
  --out=docs/dense_door_curves.png
# Issue 100: the same checkpoints with safe selection (the named variant 'safe'), argmax and the actor prior on the same 50
# held-out episodes a seed, from a worktree at commit 8ded009: 100/150 each (every seed solves all or none of its episodes).
python -m experiments.evaluate selection --workdir=runs/door200k/run/seed0,runs/door200k/run/seed1,runs/door200k/run/seed2 \
  --variant=argmax: --variant=safe --baselines=actor --episodes=50 --out=runs/door200k/selection_safe.json
python -m experiments.report results/online_door/dense200k_3seeds_7d733ad/selection_safe.json.gz
