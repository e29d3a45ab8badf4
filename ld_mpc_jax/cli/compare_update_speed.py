r"""Step time of the training update of this checkout against another checkout, in one process.

  git worktree add /tmp/baseline HEAD~1
  python -m experiments.benchmark_training versions --baseline=/tmp/baseline --config=door_open.py:cpu

The shared machines drift by ±15% within minutes, so two benchmark runs cannot rank code
versions a few percent apart. This compiles the update of the same config from both checkouts
(random parameters, the same synthetic batch) and alternates their steps, so that both see the
same load (which runs first alternates). Prints the median step time of each and the median of
the per-pair ratios (this checkout / baseline; below 1 is faster). It also prints how far the
two versions' first steps differ, from the same initial parameters, batch and key: the largest
relative difference of the metrics they share (losses, gradient norm). (Parameters after one
Adam step are no test: a gradient near 0 becomes a step of +-lr either way.) The config file is
read from this checkout.
"""

import os
import sys
import time

from absl import app, flags
import jax
import numpy as np

from ld_mpc_jax.cli.benchmark_training import load_config

_BASELINE = flags.DEFINE_string('baseline', None, 'Root of the other checkout (a git worktree).')
_CONFIG = flags.DEFINE_string('config', 'door_open.py:cpu', 'Config file, optionally :preset.')
_STEPS = flags.DEFINE_integer('steps', 40, 'Timed steps of each version (after 2 untimed).')
flags.mark_flags_as_required(['baseline'])

_HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _compile_from(root: str, config):
  """The update, state and batch built by the ld_mpc_jax package found under `root`."""
  for name in list(sys.modules):
    if name == 'ld_mpc_jax' or name.startswith('ld_mpc_jax.'):
      del sys.modules[name]
  sys.path.insert(0, root)
  try:
    from benchmarks.training import random_batch
    from ld_mpc_jax.learn import train_state
    module = os.path.abspath(sys.modules['ld_mpc_jax'].__file__)
    if not module.startswith(os.path.abspath(root) + os.sep):
      raise ImportError(f'ld_mpc_jax was imported from {module}, not from {root}')
    # A checkout from before LearnSettings builds from the config itself.
    learn = (train_state.LearnSettings.from_config(config)
             if hasattr(train_state, 'LearnSettings') else config)
    state = train_state.create_train_state(learn, jax.random.key(0))
    batch = random_batch(config, config.train.batch_size)
    update = train_state.make_update(learn)
    return update.lower(state, batch, jax.random.key(0)).compile(), state, batch
  finally:
    sys.path.remove(root)


def main(argv):
  del argv
  baseline = os.path.abspath(_BASELINE.value)
  if not os.path.isdir(os.path.join(baseline, 'ld_mpc_jax')):
    print(f'error: --baseline={_BASELINE.value} has no ld_mpc_jax package', file=sys.stderr)
    sys.exit(2)
  config = load_config(_CONFIG.value)
  versions = {'baseline': list(_compile_from(baseline, config)),
              'this': list(_compile_from(_HERE, config))}
  first = {}
  for name, v in versions.items():  # The same state, batch and key: do the versions agree?
    v[1], metrics = v[0](v[1], v[2], jax.random.key(0))
    first[name] = jax.device_get(metrics)
  shared = sorted(set(first['this']) & set(first['baseline']))
  diff = max(abs(float(first['this'][k]) - float(first['baseline'][k]))
             / max(abs(float(first['baseline'][k])), 1e-12) for k in shared)
  print(f'first step: max relative difference of the {len(shared)} shared metrics {diff:.2e}')
  times = {name: [] for name in versions}
  for i in range(1 + _STEPS.value):
    order = list(versions) if i % 2 else list(versions)[::-1]
    for name in order:
      v = versions[name]
      t0 = time.perf_counter()
      v[1], metrics = v[0](v[1], v[2], jax.random.key(i + 1))
      jax.block_until_ready((v[1], metrics))
      if i >= 1:
        times[name].append(time.perf_counter() - t0)
  ratio = np.median(np.array(times['this']) / np.array(times['baseline']))
  print(f"{_CONFIG.value}: this checkout {np.median(times['this']) * 1e3:.1f} ms, baseline "
        f"{np.median(times['baseline']) * 1e3:.1f} ms per step (medians of {_STEPS.value}); "
        f"median ratio this/baseline {ratio:.3f}")
