# Trains mt10.py:cpu (offline, the ten tasks' `mixed` scripted data) on several training seeds
# side by side on one GPU, and packs each run into $OUT as seedN.tgz for evaluation elsewhere
# (experiments.evaluate or experiments.evaluate selection on the unpacked workdir).
#   1. every task's dataset, one process per task (cached under data_cache/, as train does);
#   2. one `experiments.train` process per seed, with --config.eval.episodes=0 (train and
#      checkpoint only: the ten tasks' evaluation is CPU work, done where the runs are unpacked);
#   3. each run's latest checkpoint saved again with only its EMA parameters (what evaluation
#      reads): `params` and the optimizer state are zeroed so that three runs fit what the device
#      tool returns. Such a checkpoint evaluates exactly as the original; it does not resume
#      training.
# From the repository root: OUT=/tmp/out bash scripts/gpu/mt10.sh
#   SEEDS="0 1 2" (default), CONFIG=ld_mpc_jax/configs/mt10.py:cpu (default; :smoke for a check)
#   TRAIN_T=SECONDS: stop training at that many seconds (SIGINT; the latest checkpoint is packed,
#   and its step printed); 0 (default) lets it finish.
#   DATA_XZ=DIR: xz-compressed dataset files (NAME.npz.xz, from data_cache/) unpacked into
#   data_cache/ first, so that the datasets collected elsewhere need not be collected again
#   (push-v3's takes minutes on one core).
set -u
: "${OUT:?set OUT to the folder the packed runs go to}"
export XLA_PYTHON_CLIENT_PREALLOCATE=false PYTHONUNBUFFERED=1
SEEDS=${SEEDS:-0 1 2}
CONFIG=${CONFIG:-ld_mpc_jax/configs/mt10.py:cpu}
RUNS=${RUNS:-runs/gpu_mt10}
rm -rf "$RUNS"; mkdir -p "$RUNS"
nvidia-smi -L 2>/dev/null; git rev-parse HEAD 2>/dev/null || echo 'not a git checkout: record the commit by hand'
python3 -c "import jax, flax; print('jax', jax.__version__, 'flax', flax.__version__, jax.devices())"
start=$(date +%s)
if [ -n "${DATA_XZ:-}" ]; then
  mkdir -p data_cache
  python3 - "$DATA_XZ" <<'PY'
import concurrent.futures, glob, lzma, os, sys
def unpack(path):
  with lzma.open(path) as f, open(os.path.join('data_cache', os.path.basename(path)[:-3]), 'wb') as g:
    g.write(f.read())
  return os.path.basename(path)
with concurrent.futures.ThreadPoolExecutor(8) as pool:
  print('unpacked', sorted(pool.map(unpack, glob.glob(f'{sys.argv[1]}/*.npz.xz'))))
PY
fi
python3 - "$CONFIG" <<'PY'  # Every task's dataset, one process per task (cached ones load).
import concurrent.futures, importlib.util, sys, time
from ld_mpc_jax.envs import tasks
from ld_mpc_jax.data import sources
path, _, preset = sys.argv[1].partition(':')
spec = importlib.util.spec_from_file_location('cfg', path); mod = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mod)
config = mod.get_config(preset or None)
data, names = sources.DataSpec.from_config(config), tasks.Tasks.from_config(config).names
def collect(name):
  t = time.time()
  sources.load_dataset(data.for_task(name), progress=False)
  return f'{name} ready in {time.time() - t:.0f} s'
with concurrent.futures.ProcessPoolExecutor(len(names)) as pool:
  print('\n'.join(pool.map(collect, names)))
PY
echo "data ready at $(( $(date +%s) - start )) s"
for s in $SEEDS; do
  timeout -s INT -k 30 "${TRAIN_T:-0}" python3 -m experiments.train --config="$CONFIG" --config.seed="$s" --config.eval.episodes=0 \
    --workdir="$RUNS/seed$s" >"$RUNS/train_seed$s.log" 2>&1 &
done
sleep 60; nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv 2>/dev/null
wait
echo "trained at $(( $(date +%s) - start )) s"
for s in $SEEDS; do echo "== seed $s"; tr '\r' '\n' <"$RUNS/train_seed$s.log" | grep -v '^$' | tail -n 3; done
python3 -m experiments.report pack --out="$OUT" $(for s in $SEEDS; do echo "--workdir=$RUNS/seed$s"; done)
echo "packed at $(( $(date +%s) - start )) s"; ls -la "$OUT"
