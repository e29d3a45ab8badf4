#!/bin/bash
# CPU evaluations of the H200-trained runs (commit 474f2ea, worktree /work/wt38), in priority order.
cd /work/wt38 && . .venv/bin/activate
export MUJOCO_GL=osmesa
G=/work/runs29/gpu
C8M1=safe2x_confirm8_m1:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
K4=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_k4:},plan.num_candidates=4,plan.num_prior_candidates=1
C8=safe2x_confirm8:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max,plan.safe_confirm=True,plan.confirm_draws=8
S2=safe2x:plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max
ev() { local tag=$1 run=$2; shift 2; echo "$(date +%T) start $tag $run"
  python -m experiments.compare_selection --workdirs=$G/$run "$@" --episodes=50 --seed=0 --out=$G/$run/selection_$tag.json
  echo "$(date +%T) done $tag $run"; }
for s in 1 2; do ev k4 door_weak_seed$s --variant=$K4 --baselines=proposal; done
for r in door_weak_seed0 door_weak_seed1 door_weak_seed2; do ev argmax $r --variant=argmax: --baselines=actor; done
for r in door_weak_seed0 door_weak_seed1 door_weak_seed2; do ev c8 $r --variant=$C8 --baselines=actor; done
for r in door_weak_seed0 door_weak_seed1 door_weak_seed2; do ev s2 $r --variant=$S2 --baselines=actor; done
for r in reach_medium_seed0 reach_medium_seed1 reach_medium_seed2; do ev argmax $r --variant=argmax: --baselines=actor; done
