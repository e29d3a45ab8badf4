#!/bin/bash
# plan.fallback_drop = 0.1 on top of C8M1 (FB10), against C8M1 and the actor prior on the same 50
# held-out episodes per seed (evaluation seed 0). Commit 3c3f7da, worktree /work/wt41. Cached
# C8M1 and actor cells are read, not run again (the new field at 0 leaves their cache keys).
cd /work/wt41 && . .venv/bin/activate
export MUJOCO_GL=osmesa PYTHONUNBUFFERED=1
O=/work/runs32
R=/work/runs31/mt10
P=/work/runs27/obj/push_medium
G=/work/runs29/gpu
S=plan.safe_selection=True,plan.safe_margin=2.0,plan.safe_margin_scaling=expected_max
C8M1=safe2x_confirm8_m1:$S,plan.safe_confirm=True,plan.confirm_draws=8,plan.confirm_margin=1.0
FB=${C8M1/safe2x_confirm8_m1:/safe2x_confirm8_m1_fb10:},plan.fallback_drop=0.1
cs() { python -m experiments.compare_selection --variant=$C8M1 --variant=$FB --baselines=actor --episodes=50 --seed=0 "$@"; }
echo "$(date +%T) start peg seed1"
cs --workdirs=$R/seed1 --tasks=peg-insert-side-v3 --out=$O/fb_peg_seed1.json > $O/fb_peg_seed1.log 2>&1
echo "$(date +%T) done peg seed1 rc=$?"
for s in 0 1 2; do cs --workdirs=$P/seed$s --out=$O/fb_push_seed$s.json > $O/fb_push_seed$s.log 2>&1 & done; wait
cs --workdirs=$P/seed0,$P/seed1,$P/seed2 --out=$O/fb_push.json > $O/fb_push.log 2>&1
echo "$(date +%T) done push rc=$?"
A=reach-v3,push-v3,pick-place-v3,door-open-v3,drawer-open-v3
B=drawer-close-v3,button-press-topdown-v3,peg-insert-side-v3,window-open-v3,window-close-v3
for s in 0 1; do
  cs --workdirs=$R/seed$s --tasks=$A --out=$O/fb_mt10_seed${s}_a.json > $O/fb_mt10_seed${s}_a.log 2>&1 &
  cs --workdirs=$R/seed$s --tasks=$B --out=$O/fb_mt10_seed${s}_b.json > $O/fb_mt10_seed${s}_b.log 2>&1 &
  wait
  echo "$(date +%T) done mt10 seed$s"
done
for d in door_weak reach_medium; do
  for s in 0 1 2; do cs --workdirs=$G/${d}_seed$s --out=$O/fb_${d}_seed$s.json > $O/fb_${d}_seed$s.log 2>&1 & done; wait
  cs --workdirs=$G/${d}_seed0,$G/${d}_seed1,$G/${d}_seed2 --out=$O/fb_$d.json > $O/fb_$d.log 2>&1
  echo "$(date +%T) done $d rc=$?"
done
until grep -q "done all seed2" /work/runs31/queue_eval_gpu2.log; do sleep 30; done
cs --workdirs=$R/seed2 --tasks=$A --out=$O/fb_mt10_seed2_a.json > $O/fb_mt10_seed2_a.log 2>&1 &
cs --workdirs=$R/seed2 --tasks=$B --out=$O/fb_mt10_seed2_b.json > $O/fb_mt10_seed2_b.log 2>&1 &
wait
cs --workdirs=$R/seed0,$R/seed1,$R/seed2 --out=$O/fb_mt10.json > $O/fb_mt10.log 2>&1
echo "$(date +%T) all done rc=$?"
