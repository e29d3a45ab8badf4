#!/usr/bin/env bash
# Issue 70, sparse reward through the fine-tuning path: push-v3, `:finetune --config.online.reward=sparse`, three seeds
# in one run, each from its own seed of an offline `:cpu` push `medium` run (4,000 updates, three seeds), 50,000
# simulator steps (= 25k TD-MPC2 decisions). Worktree at commit 0e10ffd; run in two sittings (stopped at the 20,000
# checkpoint, resumed). The chain it belongs to (offline -> ft_sparse -> ft_dense -> offline control) is below.
cd "$(git rev-parse --show-toplevel)"  # a worktree at commit 0e10ffd
R=runs/push_ft
python -m experiments.train --config=door_open.py:cpu --config.task=push-v3 --config.data.preset=medium \
  --config.eval.splits=held_out --config.train.num_seeds=3 --config.train.checkpoint_every=250 --workdir=$R/offline
python -m experiments.train --config=door_open_online.py:finetune --config.task=push-v3 \
  --config.online.init_from=$R/offline --config.train.num_seeds=3 --config.eval.splits=held_out \
  --config.online.reward=sparse --workdir=$R/ft_sparse
# The run's in-process final evaluation (three training seeds one after another, about 40 min each here) was stopped;
# each seed is evaluated on its own, the same 50 held-out episodes for the planner, actor prior and proposal:
for s in 0 1 2; do
  python -m experiments.evaluate --workdir=$R/ft_sparse/seed$s --splits=held_out --seeds=0 \
    --out=$R/ft_sparse/seed$s/evaluation.json
done
# Records of the training (periodic held-out evaluations, acting log, losses), gzipped without name or time
# (`report records` needs the final evaluation's episodes.csv):
for s in 0 1 2; do for f in eval online losses; do
  gzip -9 -n -c $R/ft_sparse/seed$s/$f.csv > results/online_push/ft_sparse_0e10ffd/seed${s}_$f.csv.gz
done; done
# The evaluations, gzipped, and pooled over the training seeds (pooled.md):
for s in 0 1 2; do
  gzip -9 -n -c $R/ft_sparse/seed$s/evaluation.json > results/online_push/ft_sparse_0e10ffd/seed${s}_evaluation.json.gz
done
F=results/online_push/ft_sparse_0e10ffd
python -m experiments.report $F/seed0_evaluation.json.gz $F/seed1_evaluation.json.gz $F/seed2_evaluation.json.gz > $F/pooled.md
