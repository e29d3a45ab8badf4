#!/usr/bin/env bash
# Issue 70, the learned progress reward against the hand-made one: push-v3 with 5 demonstrations and Meta-World's
# *dense* reward, otherwise the command of ../progress_w10_1005061/run.sh without its progress flags (the safe-selection
# margins, set for the sparse reward's scale, are kept as they are). Three seeds in one run, 100k simulator steps
# (= 50k TD-MPC2 decisions). Run from a worktree at commit 251e821 (git worktree add ../wt_251e821 251e821).
# Stopped at checkpoints between sessions and resumed with the same command (48,000 was the last stop); 8,112 s of acting
# and training for the three seeds together.
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
# From main: the records here (pooled.md: the final evaluation, 50 held-out episodes a seed, the same for every policy):
python -m experiments.report records --workdir=$R --out=results/sparse_push/dense_5demos_251e821
# Paired on the same held-out episodes with the learned progress reward (paired_with_progress.md) and with the sparse
# reward alone (paired_with_sparse.md); this run's policies are tagged #dense:
D=results/sparse_push/dense_5demos_251e821
for other in progress_w10_1005061:progress v3_5demos_100k_7b652a9:sparse; do O=results/sparse_push/${other%%:*}
  python -m experiments.report $O/seed0_episodes.csv.gz+$D/seed0_episodes.csv.gz#dense \
    $O/seed1_episodes.csv.gz+$D/seed1_episodes.csv.gz#dense $O/seed2_episodes.csv.gz+$D/seed2_episodes.csv.gz#dense \
    > $D/paired_with_${other##*:}.md
done
