#!/usr/bin/env bash
# Issue 70, the recipe's one-at-a-time ablation: the sparse door-open recipe of ../v3_bc_actor_safe_22ad14c (5
# demonstrations, the same flags) without the actor prior's cloning of the demonstrations (loss.w_demo_bc=0; the seed
# waves still act with the actor prior, as in the recipe). Three seeds in one run, 30,400 simulator steps. Run from a
# worktree at commit f7e1db3 (git worktree add ../wt_f7e1db3 f7e1db3), alone on the 2-core CPU: 2,377 s acting and
# training for the three seeds, then the final evaluation (5 min).
python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/ablate/no_actor_bc \
  --config.train.num_seeds=3 --config.online.reward=sparse --config.online.demos=5 --config.online.env_steps=30000 \
  --config.online.eval_every=10000 --config.online.act_num_gaussian=0 --config.online.act_iterations=0 \
  --config.loss.w_demo_bc=0.0 --config.online.demo_seed_actor=True --config.online.act_safe_selection=True \
  --config.plan.safe_selection=True --config.plan.safe_margin=2 --config.plan.safe_margin_scaling=expected_max \
  --config.plan.safe_confirm=True --config.plan.confirm_draws=8 --config.plan.confirm_margin=1 \
  --config.plan.fallback_drop=0.1 --config.plan.fallback_floor=1000
python -m experiments.report records --workdir=runs/ablate/no_actor_bc --out=results/sparse_door_open/no_actor_bc_f7e1db3
# Paired against the recipe (the same held-out episodes; this run's policies tagged #nobc): paired_with_v3.md
R=results/sparse_door_open; for s in 0 1 2; do F+=" $R/v3_bc_actor_safe_22ad14c/seed${s}_episodes.csv.gz+$R/no_actor_bc_f7e1db3/seed${s}_episodes.csv.gz#nobc"; done
python -m experiments.report $F > $R/no_actor_bc_f7e1db3/paired_with_v3.md
