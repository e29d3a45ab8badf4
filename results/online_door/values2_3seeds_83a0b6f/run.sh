#!/usr/bin/env bash
# Issue 101: two value members instead of five (`--config.critic.num_values=2`: 1.15x the simulator steps per second in
# results/benchmarks/online_values2_epyc.md), dense door-open from scratch, three training seeds in one run, 100k simulator
# steps (= TD-MPC2's 50k decisions), to pair with results/online_door/norollout_3seeds_45fd6aa (today's :cpu, five members;
# the same config otherwise, the same held-out episodes). Worktree at commit 83a0b6f, nice 19, 2-core AMD EPYC.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 83a0b6f
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/door_values2/run \
  --config.train.num_seeds=3 --config.critic.num_values=2
python -m experiments.report records --workdir=runs/door_values2/run --out=results/online_door/values2_3seeds_83a0b6f
# Paired against five members on the same episodes:
A=results/online_door/norollout_3seeds_45fd6aa; B=results/online_door/values2_3seeds_83a0b6f
python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#values2 \
  $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#values2 $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#values2
# While acting (the proposal's share of the elites): python -m experiments.report acting $B/seed0_online.csv.gz --every=20000
# Result (6,833 s of acting and training for the three seeds, nice 19 beside other work): planner 150/150 (50, 50, 50), actor
# 150/150, proposal 126/150; against five members on the same episodes 150 vs 150 (0 / 0, p = 1). While acting (whole run, per
# seed) the proposal's share of the refinement's starting elites 41%, 44%, 41% (its share of the first round: 16 of 56).
