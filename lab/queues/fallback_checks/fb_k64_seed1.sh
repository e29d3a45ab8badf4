#!/bin/bash
# How often the fallback fires at K = 64: FF on MT10 training seed 1 again at 31b8526 (whose
# records carry fallback_at), in a copy of the run directory with an empty evaluation cache
# (checkpoint and config linked). Its outcomes should be those of ff_mt10_seed1_{a,b}.json.
cd /work/wt43 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
O=/work/runs33; W=$O/mt10_seed1_ff
S=plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max
FF=safe2x_confirm8_m1_ff:$S,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0,plan.fallback_drop=0.1,plan.fallback_floor=1000
A=reach-v3,push-v3,pick-place-v3,door-open-v3,drawer-open-v3
B=drawer-close-v3,button-press-topdown-v3,peg-insert-side-v3,window-open-v3,window-close-v3
for h in a b; do T=$A; [ $h = b ] && T=$B
  python -m experiments.compare_selection --workdirs=$W --variant=$FF --baselines=actor --tasks=$T --episodes=50 --seed=0 --out=$O/fb_k64_seed1_$h.json > $O/fb_k64_seed1_$h.log 2>&1 &
done; wait; echo "$(date +%T) done"
