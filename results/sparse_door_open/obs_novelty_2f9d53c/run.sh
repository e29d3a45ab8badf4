#!/usr/bin/env bash
# Issue 70, sparse door-open without demonstrations: the learned exploration value with members of the observation's
# change (model.novelty_target=obs), three seeds in one run, to 200k simulator steps; weight 1 -> 0 and optimism -1 -> 0
# over the run, the disagreement term off. The same flags as obs_novelty_e9760df (lost at 24,000), from the start again.
# Run from a worktree at commit 2f9d53c (git worktree add ../wt_2f9d53c 2f9d53c). The seed<N>_online.csv.gz and
# seed<N>_eval.csv.gz here are the run so far (stopped at the end of a session; the same command resumes it from its
# last checkpoint), not its end.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 2f9d53c
R=${R:-runs/sparse_door_obsnov}  # Run directory and records folder: the rerun sets both.
OUT=${OUT:-results/sparse_door_open/obs_novelty_2f9d53c}
python -m experiments.train --config=ld_mpc_jax/configs/door_open_online.py:cpu \
  --config.online.reward=sparse --config.train.num_seeds=3 --config.online.env_steps=200000 \
  --config.loss.w_novelty=1 --config.model.novelty_target=obs --config.online.act_schedule=linear \
  --config.online.act_novelty=1 --config.online.act_novelty_end=0 \
  --config.online.act_pessimism=-1 --config.online.act_pessimism_end=0 \
  --workdir=$R
# Records so far, gzipped without name or time:
for s in 0 1 2; do for f in online eval; do
  gzip -9 -n -c $R/seed$s/$f.csv > $OUT/seed${s}_$f.csv.gz
done; done
