#!/bin/bash
# Peg-insert-side: C8M1 with a larger first margin (3 x E[max]) on training seed 1, and C8M1 with
# another planner draw on training seed 0 (50/50 with evaluation key 0). Commit 1cd6f29.
cd /work/wt40 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
R=/work/runs31/mt10
S=plan.safe_selection=True,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
python -m experiments.compare_selection --workdirs=$R/seed1 --tasks=peg-insert-side-v3 \
  --variant=safe3x_confirm8_m1:$S,plan.safe_margin=3.0 --baselines=actor \
  --episodes=50 --seed=0 --out=/work/runs31/peg_seed1_m3.json > /work/runs31/peg_m3.log 2>&1 &
python -m experiments.compare_selection --workdirs=$R/seed0 --tasks=peg-insert-side-v3 \
  --variant=safe2x_confirm8_m1_key1:$S,plan.safe_margin=2.0,eval.key_seed=1 --baselines=actor \
  --episodes=50 --seed=0 --out=/work/runs31/peg_seed0_key1.json > /work/runs31/peg_s0k1.log 2>&1 &
wait
echo "$(date +%T) peg_more done"
