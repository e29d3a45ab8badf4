#!/usr/bin/env bash
# Issue 101: three seeds as three processes at once against three seeds in one process (one virtual device per seed, as runs
# train), door_open_online.py:cpu, 4,000 simulator steps each, commit 864a583, 2-core Intel Xeon, the other jobs stopped
# (SIGSTOP) while it ran. Result: 23.8 simulator steps/s per seed in one process (71.4 in all), 23.2, 23.1, 23.3 as three
# processes (69.6 in all): one process already keeps both cores busy; processes gain nothing.
cd "$(git rev-parse --show-toplevel)"
O=runs/bench/procs; mkdir -p $O
python -m experiments.benchmark_training --online_seeds=3 --online_seed_devices=0 --configs=door_open_online.py:cpu \
  --online_env_steps=4000 --out=$O/one_process.json > $O/one_process.log 2>&1
for s in 0 1 2; do
  python -m experiments.benchmark_training --online_seeds=1 --configs=door_open_online.py:cpu --config.seed=$s \
    --online_env_steps=4000 --out=$O/proc_s$s.json > $O/proc_s$s.log 2>&1 &
done
wait
