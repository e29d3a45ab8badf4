#!/bin/bash
# K = 4 on MT10 seed 0 right after its C8M1 evaluation (queue_eval.sh's own K = 4 pass then reads the cached cells).
until grep -q "done cm1 seed0" /work/runs31/queue_eval.log; do sleep 20; done
cd /work/wt40 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
R=/work/runs31/mt10
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
K4=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_k4:},plan.num_candidates=4,plan.num_prior_candidates=1
A=reach-v3,push-v3,pick-place-v3,door-open-v3,drawer-open-v3
B=drawer-close-v3,button-press-topdown-v3,peg-insert-side-v3,window-open-v3,window-close-v3
echo "$(date +%T) start k4 seed0"
python -m experiments.compare_selection --workdirs=$R/seed0 --variant=$K4 --baselines=actor --tasks=$A --episodes=50 --seed=0 --out=$R/seed0/selection_k4_a.json > /work/runs31/eval_k4_seed0_a.log 2>&1 &
python -m experiments.compare_selection --workdirs=$R/seed0 --variant=$K4 --baselines=actor --tasks=$B --episodes=50 --seed=0 --out=$R/seed0/selection_k4_b.json > /work/runs31/eval_k4_seed0_b.log 2>&1 &
wait
python -m experiments.compare_selection --workdirs=$R/seed0 --variant=$C8M1 --variant=$K4 --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs31/mt10_seed0_all.json > /work/runs31/eval_all_seed0.log 2>&1
echo "$(date +%T) done k4 seed0 rc=$?"
