# The leave-one-out variants of door_open_online.py:cpu_tanh (variants.sh: door-open-v3, training
# seed SEED, 2 by default), one process each, side by side on one GPU. Each is stopped at $T seconds by SIGINT (a
# KeyboardInterrupt wherever it is: what it did after its last checkpoint is lost) and packed
# into $OUT as NAME.tgz (the latest checkpoint and buffer, CSVs, log; split into NAME.tgz.0,
# .1, ... above 15.5 MiB). A cut run finishes anywhere with resume.sh.
# From the repository root on the GPU machine: T=470 OUT=/tmp/out bash lab/leave_one_out/leave_one_out.sh
# Other runs: VARIANTS="no_discount no_episode_shape no_update_ratio" SEED=0 T=470 OUT=... bash ...
set -u
: "${OUT:?set OUT to the folder the packed runs go to}"
. "$(dirname "$0")/variants.sh"
rm -rf runs/gpu  # A warm machine may hold an earlier call's runs: start fresh.
export XLA_PYTHON_CLIENT_PREALLOCATE=false PYTHONUNBUFFERED=1
T=${T:-500}
nvidia-smi -L; git rev-parse HEAD 2>/dev/null || echo 'not a git checkout: record the commit by hand'
python3 -c "import jax, flax; print('jax', jax.__version__, 'flax', flax.__version__, jax.devices())"
run() {  # NAME: the preset with that variant's overrides, its log in its workdir
  mkdir -p runs/gpu/$1
  timeout -s INT -k 40 $T python3 -m experiments.train $BASE $(overrides $1) --workdir=runs/gpu/$1 \
    >runs/gpu/$1/train.log 2>&1 & }
start=$(date +%s)
for name in $VARIANTS; do run $name; done
sleep 90; nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv
wait
echo "wall $(( $(date +%s) - start )) s"
for d in runs/gpu/*; do echo "== $d"; tr '\r' '\n' <$d/train.log | grep -v '^$' | tail -n 4; tail -n 2 $d/online.csv 2>/dev/null; done
python3 - <<'PY'
import os, tarfile
out = os.environ['OUT']
for name in sorted(os.listdir('runs/gpu')):
  d = f'runs/gpu/{name}'
  ck = os.path.join(d, 'checkpoints')
  steps = sorted(int(s) for s in os.listdir(ck) if s.isdigit()) if os.path.isdir(ck) else []
  last = str(steps[-1]) if steps else None
  def keep(ti):
    p = ti.name.split('/')
    if len(p) > 3 and p[2] == 'checkpoints' and p[3].isdigit() and p[3] != last: return None
    if p[-1].startswith('buffer_') and p[-1] != f'buffer_{last}.npz': return None
    return ti
  path = f'{out}/{name}.tgz'
  with tarfile.open(path, 'w:gz') as t: t.add(d, arcname=f'gpu/{name}', filter=keep)
  size = os.path.getsize(path); print(name, 'last step', last, 'tgz MiB', round(size / 2**20, 1))
  if size > 15.5 * 2**20:
    data = open(path, 'rb').read(); os.remove(path); n = 15 * 2**20
    for i in range(0, len(data), n): open(f'{path}.{i // n}', 'wb').write(data[i:i + n])
PY
ls -la $OUT
