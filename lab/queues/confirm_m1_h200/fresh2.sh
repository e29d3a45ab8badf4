#!/bin/bash
# Fresh episodes (evaluation seed 1): C8M1 vs actor prior on reach medium (H200 checkpoints) or
# push medium (/work/runs27 checkpoints). Commit 474f2ea, worktree /work/wt38. Usage: fresh2.sh reach|push
cd /work/wt38 && . .venv/bin/activate
export MUJOCO_GL=osmesa
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
case $1 in
  reach) W=/work/runs29/gpu/reach_medium_seed0,/work/runs29/gpu/reach_medium_seed1,/work/runs29/gpu/reach_medium_seed2;;
  push) W=/work/runs27/obj/push_medium/seed0,/work/runs27/obj/push_medium/seed1,/work/runs27/obj/push_medium/seed2;;
esac
python -m experiments.compare_selection --workdirs=$W --variant=$C8M1 --baselines=actor --episodes=50 --seed=1 --out=/work/runs29/eval/$1_cm1_evalseed1.json
