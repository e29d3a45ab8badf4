#!/usr/bin/env bash
# Issue 70, sparse door-open without demonstrations: the same command as obs_novelty_2f9d53c (whose run a machine reset
# lost at about 173k, before its final evaluation), run again from the start at the same commit. It is not a bitwise
# repeat: the first planner wave's rewards already differ from that run's in the sixth digit (float rounding), so it is
# a second sample of the same three seeds. It ran over several sessions, each resuming from the last checkpoint (the same
# command resumes), to 200,000 simulator steps and its final evaluation (pooled.md: 50 held-out episodes a seed).
# Run from a worktree at commit 2f9d53c (git worktree add ../wt_2f9d53c 2f9d53c).
# Started from that worktree (cd ../wt_2f9d53c && bash <this checkout>/results/.../run.sh): the first run's run.sh next to
# this one (the worktree's copy at 2f9d53c predates R and OUT) with this run's folders. That script gzips the records
# so far; the finished run's records here were packed from main instead:
#   python -m experiments.report records --workdir=$R --out=$OUT
R=runs/sparse_door_obsnov_rerun OUT=results/sparse_door_open/obs_novelty_2f9d53c_rerun \
  bash "$(dirname "$0")/../obs_novelty_2f9d53c/run.sh"

# The curves in docs/sparse.md (from main, on the committed records): dense from scratch (D), sparse with 5
# demonstrations (S) and this run (N), beside TD-MPC2's published dense door-open seeds (decisions doubled):
#   D=results/online_door/dense_3seeds_83ada3e S=results/sparse_door_open/v3_bc_actor_safe_22ad14c
#   N=results/sparse_door_open/obs_novelty_2f9d53c_rerun
#   python -m experiments.report curves --workdir=$D/seed0_,$D/seed1_,$D/seed2_ --workdir=$S/seed0_,$S/seed1_,$S/seed2_ \
#     --workdir=$N/seed0_,$N/seed1_,$N/seed2_ --anchor=docs/anchors/tdmpc2_mw-door-open.csv --max_steps=200000 \
#     --pooled --out=docs/door_dense_sparse_curves.png
