#!/bin/bash
# MT10 training seed 1, peg-insert-side-v3 only: C8M1 was 45/50 against the actor prior's 50/50.
# The planner's own spread (C8M1 with other draws), confirmation margin 2, margin 2 x E[max]
# alone and the argmax, on the same 50 held-out episodes (evaluation seed 0). Commit 1cd6f29.
cd /work/wt40 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
R=/work/runs31/mt10
S=plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max
C8M1=safe2x_confirm8_m1:$S,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
python -m experiments.compare_selection --workdirs=$R/seed1 --tasks=peg-insert-side-v3 \
  --variant=$C8M1 --variant=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_key1:},eval.key_seed=1 \
  --variant=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_key2:},eval.key_seed=2 \
  --variant=safe2x_confirm8:$S,plan.safe_confirm=True,plan.confirm_draws=8 \
  --variant=safe2x:$S --variant=argmax: \
  --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs31/peg_seed1.json
echo "$(date +%T) peg done rc=$?"
