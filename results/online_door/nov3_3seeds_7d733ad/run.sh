#!/usr/bin/env bash
# Issue 100, item 2: the learned exploration value that rescued dead door seed 2 alone (../seed2_novelty_cf3ef98), on
# all three training seeds in one run: dense door-open from scratch, :cpu, 100k simulator steps, the flags of that
# rerun. From a worktree at commit 7d733ad (git worktree add ../wt_7d733ad 7d733ad), resumed from its checkpoints
# across two sessions; 10,555 s of acting and training for the three seeds together.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_nov3/run \
  --config.train.num_seeds=3 --config.loss.w_novelty=1 --config.model.novelty_target=obs \
  --config.online.act_schedule=linear --config.online.act_novelty=1 --config.online.act_novelty_end=0 \
  --config.online.act_pessimism=-1 --config.online.act_pessimism_end=0
python -m experiments.report records --workdir=runs/door_nov3/run --out=results/online_door/nov3_3seeds_7d733ad
# Paired with the run without it (the same preset and steps, commit 83ada3e) on the same 50 held-out episodes a seed:
python -m experiments.report $(for s in 0 1 2; do echo "results/online_door/dense_3seeds_83ada3e/seed${s}_episodes.csv.gz+results/online_door/nov3_3seeds_7d733ad/seed${s}_episodes.csv.gz#nov"; done)
