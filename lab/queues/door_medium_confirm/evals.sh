#!/bin/bash
# door-open `medium` (door_open.py:cpu, trained by train.sh): C8M1 vs actor prior and proposal, then K = 4,
# every policy on the same 50 held-out episodes per seed (evaluation seed 0). Commit 1ca1c8b, worktree /work/wt39.
cd /work/wt39 && . .venv/bin/activate
export MUJOCO_GL=osmesa
R=/work/runs30/door_medium
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
K4=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_k4:},plan.num_candidates=4,plan.num_prior_candidates=1
ev() { local tag=$1 s=$2; shift 2; echo "$(date +%T) start $tag seed$s"
  python -m experiments.compare_selection --workdirs=$R/seed$s "$@" --episodes=50 --seed=0 --out=$R/seed$s/selection_$tag.json > /work/runs30/eval_${tag}_seed$s.log 2>&1
  echo "$(date +%T) done $tag seed$s rc=$?"; }
for s in 0 1 2; do ev cm1 $s --variant=$C8M1 --baselines=actor,proposal & done
wait
python -m experiments.compare_selection --workdirs=$R/seed0,$R/seed1,$R/seed2 --variant=$C8M1 --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs30/door_medium_cm1.json
for s in 0 1 2; do ev k4 $s --variant=$K4 --baselines=actor & done
wait
python -m experiments.compare_selection --workdirs=$R/seed0,$R/seed1,$R/seed2 --variant=$C8M1 --variant=$K4 --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs30/door_medium_all.json
echo "$(date +%T) all done"
