#!/bin/bash
# door-open weak (H200 checkpoints), fresh episodes (evaluation seed 1): C8M1 vs actor prior. Commit 474f2ea, worktree /work/wt38.
cd /work/wt38 && . .venv/bin/activate
export MUJOCO_GL=osmesa
G=/work/runs29/gpu
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
python -m experiments.compare_selection --workdirs=$G/door_weak_seed0,$G/door_weak_seed1,$G/door_weak_seed2 --variant=$C8M1 --baselines=actor --episodes=50 --seed=1 --out=/work/runs29/eval/door_weak_cm1_evalseed1.json
