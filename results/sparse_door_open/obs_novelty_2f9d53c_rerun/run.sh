#!/usr/bin/env bash
# Issue 70, sparse door-open without demonstrations: the same command as obs_novelty_2f9d53c (whose run a machine reset
# lost at about 173k, before its final evaluation), run again from the start at the same commit. It is not a bitwise
# repeat: the first planner wave's rewards already differ from that run's in the sixth digit (float rounding), so it is
# a second sample of the same three seeds. The seed<N>_online.csv.gz and seed<N>_eval.csv.gz here are the run so far
# (stopped at the end of a session; the same command resumes it from its last checkpoint), not its end.
# Run from a worktree at commit 2f9d53c (git worktree add ../wt_2f9d53c 2f9d53c).
# Started from that worktree (cd ../wt_2f9d53c && bash <this checkout>/results/.../run.sh): the first run's run.sh next to
# this one (the worktree's copy at 2f9d53c predates R and OUT) with this run's folders.
R=runs/sparse_door_obsnov_rerun OUT=results/sparse_door_open/obs_novelty_2f9d53c_rerun \
  bash "$(dirname "$0")/../obs_novelty_2f9d53c/run.sh"
