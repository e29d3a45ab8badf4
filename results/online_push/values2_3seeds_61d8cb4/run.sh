#!/usr/bin/env bash
# Issue 101: two value members instead of five (`--config.critic.num_values=2`: 1.15x the simulator steps per second in
# results/benchmarks/online_values2_epyc.md), dense push-v3 from scratch, three training seeds in one run, 100k simulator
# steps (= TD-MPC2's 50k decisions), to pair with results/online_push/norollout_3seeds_45fd6aa (today's :cpu, five members;
# the same config otherwise, the same held-out episodes). Worktree at commit 61d8cb4, nice 19, 2-core AMD EPYC, 2026-12-08.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 61d8cb4
python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 --workdir=runs/push_values2/run \
  --config.train.num_seeds=3 --config.critic.num_values=2
python -m experiments.report records --workdir=runs/push_values2/run --out=results/online_push/values2_3seeds_61d8cb4
# Paired against five members on the same episodes:
A=results/online_push/norollout_3seeds_45fd6aa; B=results/online_push/values2_3seeds_61d8cb4
python -m experiments.report $A/seed0_episodes.csv.gz+$B/seed0_episodes.csv.gz#values2 \
  $A/seed1_episodes.csv.gz+$B/seed1_episodes.csv.gz#values2 $A/seed2_episodes.csv.gz+$B/seed2_episodes.csv.gz#values2
# Result (4,457 s of acting and training for the three seeds, nice 19, mostly alone on the CPU): planner 31/150 (8, 4, 19),
# actor 24/150, proposal 12/150; against five members on the same episodes 53 vs 31 (five only / two only: 44 / 22,
# p = 0.0092): two members lose on push. Five stay the default. While acting (whole run, per seed) the proposal won 9% of
# planned decisions and was 29-30% of the refinement's starting elites (29% of the first round).
