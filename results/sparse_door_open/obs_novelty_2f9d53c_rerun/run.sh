#!/usr/bin/env bash
# Issue 70, sparse door-open without demonstrations: the same command as obs_novelty_2f9d53c (whose run a machine reset
# lost at about 173k, before its final evaluation), run again from the start at the same commit. It is not a bitwise
# repeat: the first planner wave's rewards already differ from that run's in the sixth digit (float rounding), so it is
# a second sample of the same three seeds. The seed<N>_online.csv.gz and seed<N>_eval.csv.gz here are the run so far
# (stopped at the end of a session; the same command resumes it from its last checkpoint), not its end.
# Run from a worktree at commit 2f9d53c (git worktree add ../wt_2f9d53c 2f9d53c).
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 2f9d53c
R=runs/sparse_door_obsnov_rerun
python -m experiments.train --config=ld_mpc_jax/configs/door_open_online.py:cpu \
  --config.online.reward=sparse --config.train.num_seeds=3 --config.online.env_steps=200000 \
  --config.loss.w_novelty=1 --config.model.novelty_target=obs --config.online.act_schedule=linear \
  --config.online.act_novelty=1 --config.online.act_novelty_end=0 \
  --config.online.act_pessimism=-1 --config.online.act_pessimism_end=0 \
  --workdir=$R
# Records so far, gzipped without name or time:
for s in 0 1 2; do for f in online eval; do
  gzip -9 -n -c $R/seed$s/$f.csv > results/sparse_door_open/obs_novelty_2f9d53c_rerun/seed${s}_$f.csv.gz
done; done
