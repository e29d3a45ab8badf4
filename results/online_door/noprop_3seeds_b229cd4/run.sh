#!/usr/bin/env bash
# Issue 100, item 3, the fallback: acting without the diffusion proposal's candidates (online.act_proposal=False; evaluation
# keeps them), dense door-open from scratch, :cpu, three training seeds in one run, 100k simulator steps. From a worktree at
# commit b229cd4 (git worktree add ../wt_b229cd4 b229cd4); 4,954 s of acting and training for the three seeds together.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_noprop3 \
  --config.train.num_seeds=3 --config.online.act_proposal=False
python -m experiments.report records --workdir=runs/door_noprop3 --out=results/online_door/noprop_3seeds_b229cd4
# Paired with the run with them (the same preset and steps, commit 83ada3e) on the same 50 held-out episodes a seed:
python -m experiments.report $(for s in 0 1 2; do echo "results/online_door/dense_3seeds_83ada3e/seed${s}_episodes.csv.gz+results/online_door/noprop_3seeds_b229cd4/seed${s}_episodes.csv.gz#noprop"; done)
# Issue 100: the planner below its actor prior is argmax selection's doing. The same checkpoints evaluated with safe selection
# (plan.safe_selection=True, the named variant 'safe'), argmax and the actor prior on the same 50 held-out episodes a seed,
# from a worktree at commit 8ded009 (about 50 min at nice 19 beside two runs): selection_safe.md, selection_safe.json.gz.
python -m experiments.evaluate selection --workdir=runs/door_noprop3/seed0,runs/door_noprop3/seed1,runs/door_noprop3/seed2 \
  --variant=argmax: --variant=safe --baselines=actor --episodes=50 --out=runs/door_noprop3/selection_safe.json
python -m experiments.report results/online_door/noprop_3seeds_b229cd4/selection_safe.json.gz
