# Finishes a leave_one_out.sh run on a CPU from its latest checkpoint: the same train command
# (variants.sh) on the same workdir, pinned to one core. The resumed run drops the log rows
# written after that checkpoint before the cut.
#   bash experiments/gpu/resume.sh NAME WORKDIR CORE      e.g. no_search runs/gpu/no_search 0
set -eu
. "$(dirname "$0")/variants.sh"
flags=$(overrides "$1")
exec taskset -c "$3" python -m experiments.train $BASE $flags --workdir="$2"
