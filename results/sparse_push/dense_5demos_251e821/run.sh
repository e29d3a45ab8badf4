#!/usr/bin/env bash
# Issue 70, the learned progress reward against the hand-made one: push-v3 with 5 demonstrations and Meta-World's
# *dense* reward, otherwise the command of ../progress_w10_1005061/run.sh without its progress flags (the safe-selection
# margins, set for the sparse reward's scale, are kept as they are). Three seeds in one run, 100k simulator steps
# (= 50k TD-MPC2 decisions). Run from a worktree at commit 251e821 (git worktree add ../wt_251e821 251e821).
# The seed<N>_eval.csv.gz and seed<N>_online.csv.gz here are the run so far (stopped at its 48,000 checkpoint at the end
# of a session; the same command resumes it), not its end.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 251e821
R=runs/push_dense_demos
python -m experiments.train --config=door_open_online.py:cpu --config.task=push-v3 \
  --workdir=$R --config.train.num_seeds=3 --config.online.reward=dense \
  --config.online.demos=5 --config.online.env_steps=100000 --config.online.eval_every=20000 \
  --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=1.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000
# Records so far, gzipped without name or time (when finished: python -m experiments.report records --workdir=$R
# --out=results/sparse_push/dense_5demos_251e821):
for s in 0 1 2; do for f in eval online; do
  gzip -9 -n -c $R/seed$s/$f.csv > results/sparse_push/dense_5demos_251e821/seed${s}_$f.csv.gz
done; done
