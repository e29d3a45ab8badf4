# Finishes a leave_one_out.sh run on a CPU from its latest checkpoint: the same train command
# (variants.sh) on the same workdir, pinned to one core. The resumed run drops the log rows
# written after that checkpoint before the cut. On an empty WORKDIR it trains the variant from
# scratch; SEED=N picks another training seed (the default is 2, as leave_one_out.sh).
#   bash lab/leave_one_out/resume.sh NAME WORKDIR CORE      e.g. no_search runs/gpu/no_search 0
#   SEED=0 bash lab/leave_one_out/resume.sh no_search runs/loo/no_search_seed0 1
set -eu
. "$(dirname "$0")/variants.sh"
[ $# -eq 3 ] || { echo "usage: [SEED=N] bash lab/leave_one_out/resume.sh NAME WORKDIR CORE" >&2; exit 2; }
flags=$(overrides "$1")
exec taskset -c "$3" python -m experiments.train $BASE $flags --workdir="$2"
