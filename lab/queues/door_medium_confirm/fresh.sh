#!/bin/bash
# door-open `medium` checkpoints (train.sh): C8M1 vs actor prior on fresh episodes (evaluation seed 1), and the argmax on
# evaluation seed 0 (its caches beside the others'). Commit 1ca1c8b, worktree /work/wt39.
cd /work/wt39 && . .venv/bin/activate
export MUJOCO_GL=osmesa
R=/work/runs30/door_medium
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
ev() { local tag=$1 s=$2 seed=$3; shift 3; echo "$(date +%T) start $tag seed$s"
  python -m experiments.compare_selection --workdirs=$R/seed$s "$@" --episodes=50 --seed=$seed --out=$R/seed$s/selection_$tag.json > /work/runs30/eval_${tag}_seed$s.log 2>&1
  echo "$(date +%T) done $tag seed$s rc=$?"; }
for s in 0 1 2; do ev fresh $s 1 --variant=$C8M1 --baselines=actor & done
wait
python -m experiments.compare_selection --workdirs=$R/seed0,$R/seed1,$R/seed2 --variant=$C8M1 --baselines=actor --episodes=50 --seed=1 --out=/work/runs30/door_medium_cm1_evalseed1.json
for s in 0 1 2; do ev argmax $s 0 --variant=argmax: --baselines=actor & done
wait
python -m experiments.compare_selection --workdirs=$R/seed0,$R/seed1,$R/seed2 --variant=$C8M1 --variant=argmax: --baselines=actor,proposal --episodes=50 --seed=0 --out=/work/runs30/door_medium_argmax.json
echo "$(date +%T) all done"
