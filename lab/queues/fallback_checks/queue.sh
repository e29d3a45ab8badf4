#!/bin/bash
# C8M1 with the fallback (FF) on what was not measured yet: door-open `medium` (evaluation seed 0),
# fresh episodes (evaluation seed 1) on the five settings (MT10: peg-insert-side, the task the
# fallback's numbers were chosen on), and K = 4 with the fallback. Commit 31b8526 (records say
# when the fallback fired, `fallback_at`), worktree /work/wt43; the first step (door-open
# `medium`, evaluation seed 0) ran at 160857f (/work/wt42) and was read from the cache here.
# C8M1, K4 and actor cells already evaluated are read from each run's evals/ cache.
cd /work/wt43 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
O=/work/runs33
R=/work/runs31/mt10
P=/work/runs27/obj/push_medium
G=/work/runs29/gpu
D=/work/runs30/door_medium
S=plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max
C8M1=safe2x_confirm8_m1:$S,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
FF=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_ff:},plan.fallback_drop=0.1,plan.fallback_floor=1000
K4=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_k4:},plan.num_candidates=4,plan.num_prior_candidates=1
FFK4=${FF/safe2x_confirm8_m1_ff:/safe2x_confirm8_m1_ff_k4:},plan.num_candidates=4,plan.num_prior_candidates=1
cs() { python -m experiments.compare_selection --variant=$C8M1 --baselines=actor --episodes=50 "$@"; }
dirs() { echo $1$2seed0,$1$2seed1,$1$2seed2; }
setting() { # name, workdir prefix
  case $1 in
    door_medium) echo $D/;; push) echo $P/;; door_weak) echo $G/door_weak_;; reach_medium) echo $G/reach_medium_;;
  esac; }
per_seed() { # tag, setting, eval seed, extra variants...
  local tag=$1 name=$2 es=$3; shift 3; local W=$(setting $name)
  for s in 0 1 2; do cs --workdirs=${W}seed$s --seed=$es "$@" --out=$O/${tag}_${name}_seed$s.json > $O/${tag}_${name}_seed$s.log 2>&1 & done; wait
  cs --workdirs=$(dirs $W) --seed=$es "$@" --out=$O/${tag}_${name}.json > $O/${tag}_${name}.log 2>&1
  echo "$(date +%T) done $tag $name rc=$?"; }
echo "$(date +%T) start"
per_seed ff door_medium 0 --variant=$FF
per_seed fresh push 1 --variant=$FF
A=reach-v3,push-v3,pick-place-v3,door-open-v3,drawer-open-v3
B=drawer-close-v3,button-press-topdown-v3,peg-insert-side-v3,window-open-v3,window-close-v3
for s in 1 0 2; do
  cs --workdirs=$R/seed$s --seed=0 --variant=$FF --variant=$K4 --variant=$FFK4 --tasks=$A --out=$O/k4_mt10_seed${s}_a.json > $O/k4_mt10_seed${s}_a.log 2>&1 &
  cs --workdirs=$R/seed$s --seed=0 --variant=$FF --variant=$K4 --variant=$FFK4 --tasks=$B --out=$O/k4_mt10_seed${s}_b.json > $O/k4_mt10_seed${s}_b.log 2>&1 &
  wait; echo "$(date +%T) done k4 mt10 seed$s"
done
for n in door_weak reach_medium door_medium; do per_seed fresh $n 1 --variant=$FF; done
for n in push door_weak reach_medium door_medium; do per_seed k4 $n 0 --variant=$FF --variant=$K4 --variant=$FFK4; done
for s in 0 1 2; do cs --workdirs=$R/seed$s --seed=1 --variant=$FF --tasks=peg-insert-side-v3 --out=$O/fresh_peg_seed$s.json > $O/fresh_peg_seed$s.log 2>&1 & done; wait
echo "$(date +%T) done fresh peg"
echo "$(date +%T) all done"
