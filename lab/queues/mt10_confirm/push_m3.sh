#!/bin/bash
# push-v3 `medium` (the three checkpoints of results/records/push_medium_confirm): C8M1 with a first
# margin of 3 x E[max] against the actor prior on the same 50 held-out episodes per seed
# (evaluation seed 0). Commit 1cd6f29 (planner code as at 8a0b721, which evaluated the others).
cd /work/wt40 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
P=/work/runs27/obj/push_medium
V=safe3x_confirm8_m1:plan.safe_selection=True,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0,plan.safe_margin=3.0
for s in 0 1 2; do
  python -m experiments.compare_selection --workdirs=$P/seed$s --variant=$V --baselines=actor \
    --episodes=50 --seed=0 --out=/work/runs31/push_m3_seed$s.json > /work/runs31/push_m3_seed$s.log 2>&1 &
done
wait
python -m experiments.compare_selection --workdirs=$P/seed0,$P/seed1,$P/seed2 --variant=$V --baselines=actor \
  --episodes=50 --seed=0 --out=/work/runs31/push_m3.json > /work/runs31/push_m3.log 2>&1
echo "$(date +%T) push_m3 done rc=$?"
