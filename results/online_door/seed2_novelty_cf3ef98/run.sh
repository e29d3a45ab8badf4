#!/usr/bin/env bash
# Issue 100, a dead seed rerun: dense door-open from scratch, :cpu, training seed 2 alone (the seed that never succeeded
# in ../dense_3seeds_83ada3e), with the learned exploration value of the sparse no-demo run (obs target, weight 1 -> 0
# and optimism -1 -> 0 over the run), 100k simulator steps. From a worktree at commit cf3ef98 (provenance.jsonl here is
# the run's own record of its commit and command); 2,870 s of acting and training on the 2-core CPU.
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_seed2_nov \
  --config.seed=2 --config.loss.w_novelty=1 --config.model.novelty_target=obs --config.online.act_schedule=linear \
  --config.online.act_novelty=1 --config.online.act_novelty_end=0 \
  --config.online.act_pessimism=-1 --config.online.act_pessimism_end=0
python -m experiments.report records --workdir=runs/door_seed2_nov --out=results/online_door/seed2_novelty_cf3ef98
# Paired with the dead seed on the same 50 held-out episodes:
python -m experiments.report \
  'results/online_door/dense_3seeds_83ada3e/seed2_episodes.csv.gz+results/online_door/seed2_novelty_cf3ef98/episodes.csv.gz#nov'
