# Finishes a leave_one_out.sh run on a CPU from its latest checkpoint: the same train command on
# the same workdir, pinned to one core.
#   bash experiments/gpu/resume.sh WORKDIR CORE OVERRIDES...
# e.g. bash experiments/gpu/resume.sh runs/gpu/no_search 0 --config.online.act_num_gaussian=0 --config.online.act_iterations=0
set -eu
workdir=$1; core=$2; shift 2
exec taskset -c "$core" python -m experiments.train \
  --config=experiments/configs/door_open_online.py:cpu_tanh --config.seed=2 \
  --config.online.plan_chunk=4 "$@" --workdir="$workdir"
