#!/usr/bin/env bash
# The ablation ladder re-measured with committed records: the :ablation preset (door-open, mixed data, 3 training seeds,
# 50 held-out episodes each, the same episodes for every policy of a seed), variant 2 (single-step diffusion proposal +
# MLP dynamics) and 5 (LD-MPC), the baselines on LD-MPC's checkpoints and the observation-noise sweep (seed 0).
# Run from a worktree at commit 2632053 (git worktree add ../wt_2632053 2632053); the first two trainings beside
# another run (niced), the rest alone. Records here: <variant>_seed<s>_episodes.csv.gz (the variant's own evaluation),
# ldmpc_seed<s>_eval_<baseline>.json.gz and ldmpc_seed<s>_noise_<policy>_<std>.json.gz (the sweep's evaluations on
# LD-MPC's checkpoints), each variant's report.md, and the sweep's ablations.md / .json / .png.
python -m experiments.train ablations --workdir=runs/ablations --expert=False --variants=diffstep_mlp,ldmpc \
  --config.eval.splits="('held_out',)"
# The README's numbers from these records (a baseline joins its checkpoint's episodes.csv with '+'):
O=results/ablations/door_mixed_2632053
python -m experiments.report $(for s in 0 1 2; do echo $O/ldmpc_seed$s\_episodes.csv.gz+$O/ldmpc_seed$s\_eval_actor.json.gz; done)
python -m experiments.report $(for s in 0 1 2; do echo $O/ldmpc_seed$s\_episodes.csv.gz+$O/diffstep_mlp_seed$s\_episodes.csv.gz#v2; done)
