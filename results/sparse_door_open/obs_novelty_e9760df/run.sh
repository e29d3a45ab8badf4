#!/usr/bin/env bash
# Issue 70, sparse door-open without demonstrations: the learned exploration value with members of the observation's
# change (model.novelty_target=obs), three seeds in one run, to 200k simulator steps; weight 1 -> 0 and optimism -1 -> 0
# over the run, the disagreement term off. Run from a worktree at commit e9760df (git worktree add ../wt_e9760df e9760df).
# The seed<N>_online.csv.gz here are the run so far (its training waves to 24,000 simulator steps), not its end.
python -m experiments.train --config=ld_mpc_jax/configs/door_open_online.py:cpu \
  --config.online.reward=sparse --config.train.num_seeds=3 --config.online.env_steps=200000 \
  --config.loss.w_novelty=1 --config.model.novelty_target=obs --config.online.act_schedule=linear \
  --config.online.act_novelty=1 --config.online.act_novelty_end=0 \
  --config.online.act_pessimism=-1 --config.online.act_pessimism_end=0 \
  --workdir=runs/sparse_door_obsnov
