# Trains single-task offline settings (door_open.py:cpu with another task and data preset) on
# several training seeds side by side on one GPU, and packs each run into $OUT as NAME_seedN.tgz
# for evaluation elsewhere (experiments.evaluate selection on the unpacked workdir). The same steps
# as mt10.sh: datasets unpacked from DATA_XZ (collect them where MuJoCo runs: the Meta-World wheel
# carried without its textures trains but cannot simulate), one `experiments.train` per setting
# and seed with --config.eval.episodes=0, each latest checkpoint saved again with its EMA
# parameters only (it evaluates exactly as trained and does not resume training).
# From the repository root:
#   OUT=/tmp/out SETTINGS="push_medium:push-v3:medium reach_medium:reach-v3:medium" \
#     DATA_XZ=.gpu/data bash scripts/gpu/offline.sh
#   SEEDS="0 1 2" (default), CONFIG=ld_mpc_jax/configs/door_open.py:cpu (default), RUNS (default
#   runs/gpu_offline), DATA (config.data.dir, default data_cache), PY (default python3),
#   TRAIN_T=SECONDS stops training that many seconds after the start (SIGINT; the latest
#   checkpoint is packed).
#   EVAL_FILE=PATH: after training, each line `TAG ARGS...` runs `experiments.evaluate selection
#   ARGS --workdir=RUN --out=RUN/selection_TAG.json` on every run, the lines in order and the
#   runs side by side, all stopped EVAL_T seconds (default 300) after they start; the per-policy
#   caches (RUN/evals/) and the JSONs travel in the packed run, so that compare_selection here
#   pools the seeds without evaluating again.
#   BENCH="ARGS": then `experiments.benchmark_planning ARGS` alone on the machine (at most
#   BENCH_T seconds, default 120); its files and every log go into $OUT/logs.tgz.
set -u
: "${OUT:?set OUT to the folder the packed runs go to}"
: "${SETTINGS:?set SETTINGS to NAME:TASK:PRESET items}"
export XLA_PYTHON_CLIENT_PREALLOCATE=false PYTHONUNBUFFERED=1
SEEDS=${SEEDS:-0 1 2}
CONFIG=${CONFIG:-ld_mpc_jax/configs/door_open.py:cpu}
RUNS=${RUNS:-runs/gpu_offline}
DATA=${DATA:-data_cache}  # config.data.dir: where datasets are unpacked, collected or read.
PY=${PY:-python3}
rm -rf "$RUNS"; mkdir -p "$RUNS" "$OUT" "$DATA"
nvidia-smi -L 2>/dev/null; git rev-parse HEAD 2>/dev/null || echo 'not a git checkout: record the commit by hand'
"$PY" -c "import jax, flax; print('jax', jax.__version__, 'flax', flax.__version__, jax.devices())"
start=$(date +%s)
if [ -n "${DATA_XZ:-}" ]; then
  "$PY" -c "import glob, lzma, os, shutil, sys
for p in glob.glob(sys.argv[1] + '/*.npz.xz'):
  with lzma.open(p) as f, open(os.path.join(sys.argv[2], os.path.basename(p)[:-3]), 'wb') as g: shutil.copyfileobj(f, g)
print(os.listdir(sys.argv[2]))" "$DATA_XZ" "$DATA"
fi
# Compiling the training step takes about a minute alone on an H100 and several with six
# compiling at once, so the first seed of each setting compiles first and writes JAX's persistent
# cache; the other seeds start once those have logged a training step, and read it.
export JAX_COMPILATION_CACHE_DIR=${JAX_COMPILATION_CACHE_DIR:-$(cd "$RUNS" && pwd)/jax_cache}
export JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS=0
deadline=$(( start + ${TRAIN_T:-100000} ))
names=()
train() {  # NAME TASK PRESET SEED
  local n="${1}_seed$4"; names+=("$n")
  timeout -s INT -k 30 "$(( deadline - $(date +%s) ))" "$PY" -m experiments.train \
    --config="$CONFIG" --config.task="$2" --config.data.preset="$3" \
    --config.eval.splits=held_out --config.eval.episodes=0 --config.seed="$4" --config.data.dir="$DATA" \
    --workdir="$RUNS/$n" >"$RUNS/$n.log" 2>&1 &
}
set -- $SEEDS; first=$1; shift; rest="$*"
for item in $SETTINGS; do IFS=: read -r name task preset <<<"$item"; train "$name" "$task" "$preset" "$first"; done
while [ "$(date +%s)" -lt "$deadline" ]; do
  ready=1
  for n in "${names[@]}"; do
    tr '\r' '\n' <"$RUNS/$n.log" | grep -qE ' [1-9][0-9]*/[0-9]+ \[' || ready=0
  done
  [ $ready = 1 ] || [ -z "$(jobs -r)" ] && break; sleep 2
done
echo "first seeds compiled at $(( $(date +%s) - start )) s"
for s in $rest; do
  for item in $SETTINGS; do IFS=: read -r name task preset <<<"$item"; train "$name" "$task" "$preset" "$s"; done
done
sleep 20; nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv 2>/dev/null
wait
echo "trained at $(( $(date +%s) - start )) s"
for n in "${names[@]}"; do echo "== $n"; tr '\r' '\n' <"$RUNS/$n.log" | grep -v '^$' | tail -n 2; done
if [ -n "${EVAL_FILE:-}" ]; then
  end=$(( $(date +%s) + ${EVAL_T:-300} ))
  for n in "${names[@]}"; do
    while read -r tag args; do
      [ -z "$tag" ] && continue
      left=$(( end - $(date +%s) )); [ "$left" -le 5 ] && break
      # shellcheck disable=SC2086
      timeout -s INT -k 20 "$left" "$PY" -m experiments.evaluate selection $args \
        --workdir="$RUNS/$n" --out="$RUNS/$n/selection_$tag.json" >>"$RUNS/${n}_eval.log" 2>&1
    done <"$EVAL_FILE" &
  done
  wait
  echo "evaluated at $(( $(date +%s) - start )) s"
  for n in "${names[@]}"; do echo "== $n"; ls "$RUNS/$n" | grep selection_ || tail -n 3 "$RUNS/${n}_eval.log"; done
fi
"$PY" -m experiments.report pack --out="$OUT" "${names[@]/#/--workdir=$RUNS/}"
echo "packed at $(( $(date +%s) - start )) s"
if [ -n "${BENCH:-}" ]; then
  # shellcheck disable=SC2086
  timeout -s INT -k 20 "${BENCH_T:-120}" "$PY" -m experiments.benchmark_planning $BENCH \
    --out="$RUNS/benchmark_planning.json" >"$RUNS/benchmark.log" 2>&1
  tail -n 12 "$RUNS/benchmark.log"
fi
tar czf "$OUT/logs.tgz" -C "$RUNS" $(cd "$RUNS" && ls -d *.log *.json *.md 2>/dev/null)
ls -la "$OUT"
