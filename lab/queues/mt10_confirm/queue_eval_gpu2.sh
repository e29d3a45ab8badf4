#!/bin/bash
# MT10 seed 2 trained on a lent H200 (experiments/gpu/mt10.sh at c385245, SEEDS=2): C8M1 against the actor prior and the proposal on every task,
# then K = 4 (seeds 1 and 2; seed 0 ran before); every policy on the same 50 held-out episodes per task and seed (evaluation seed 0).
# Commit 1cd6f29, worktree /work/wt40. Each seed starts once its training has finished; its ten
# tasks run in two processes of five, then one call per seed reads the cached cells into one file.
cd /work/wt40 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
R=/work/runs31/mt10
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
K4=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_k4:},plan.num_candidates=4,plan.num_prior_candidates=1
A=reach-v3,push-v3,pick-place-v3,door-open-v3,drawer-open-v3
B=drawer-close-v3,button-press-topdown-v3,peg-insert-side-v3,window-open-v3,window-close-v3
ev() { local tag=$1 s=$2; shift 2; echo "$(date +%T) start $tag seed$s"
  python -m experiments.compare_selection --workdirs=$R/seed$s "$@" --tasks=$A --episodes=50 --seed=0 --out=$R/seed$s/selection_${tag}_a.json > /work/runs31/eval_${tag}_seed${s}_a.log 2>&1 &
  python -m experiments.compare_selection --workdirs=$R/seed$s "$@" --tasks=$B --episodes=50 --seed=0 --out=$R/seed$s/selection_${tag}_b.json > /work/runs31/eval_${tag}_seed${s}_b.log 2>&1 &
  wait
  python -m experiments.compare_selection --workdirs=$R/seed$s "$@" --episodes=50 --seed=0 --out=$R/seed$s/selection_$tag.json > /work/runs31/eval_${tag}_seed$s.log 2>&1
  echo "$(date +%T) done $tag seed$s rc=$?"; }
for s in 2; do
  ev cm1 $s --variant=$C8M1 --baselines=actor,proposal
  ev k4 $s --variant=$K4 --baselines=actor
  python -m experiments.compare_selection --workdirs=$R/seed$s --variant=$C8M1 --variant=$K4 --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs31/mt10_seed${s}_all.json > /work/runs31/eval_all_seed$s.log 2>&1
  echo "$(date +%T) done all seed$s rc=$?"
done
python -m experiments.compare_selection --workdirs=$R/seed0,$R/seed1,$R/seed2 --variant=$C8M1 --variant=$K4 --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs31/mt10_pooled.json > /work/runs31/eval_pooled.log 2>&1
echo "$(date +%T) all done rc=$?"
