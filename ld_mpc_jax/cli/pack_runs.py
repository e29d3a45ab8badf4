"""Packs training runs for evaluation elsewhere: each run's latest checkpoint saved again with its
EMA parameters alone, the rest of the run directory beside it, as OUT/NAME.tgz.

  python -m experiments.report pack --out=DIR --workdir=runs/gpu_offline/push_medium_seed0 ...

`params` and the optimizer state are zeroed (they compress to almost nothing), so such a
checkpoint evaluates exactly as the original and does not resume training. The GPU launchers
(scripts/gpu/mt10.sh, offline.sh) pack their runs with it, since the device tool returns at
most 64 MiB.
"""

import os
import shutil
import tarfile
import tempfile

from absl import app, flags


def pack(workdir: str, out: str) -> str | None:
  """OUT/NAME.tgz of run `workdir` with EMA parameters only (NAME: its folder name), or None
  when it holds no checkpoint."""
  import jax
  import jax.numpy as jnp
  import orbax.checkpoint as ocp
  from ld_mpc_jax.learn import checkpointing
  from ld_mpc_jax.learn.train_state import LearnSettings
  workdir = os.path.normpath(workdir)
  name = os.path.basename(workdir)
  config = checkpointing.load_config(workdir)
  manager = checkpointing.checkpoint_manager(workdir)
  step, state, _ = checkpointing.restore_intact(  # Newest intact step.
      manager, checkpointing.abstract_state(LearnSettings.from_config(config)))
  if state is None:
    return None
  tmp = tempfile.mkdtemp()
  staging = os.path.join(tmp, name)
  shutil.copytree(workdir, staging, ignore=shutil.ignore_patterns('checkpoints',
                                                                     'damaged_checkpoints'))
  zero = lambda tree: jax.tree.map(jnp.zeros_like, tree)
  state = state.replace(params=zero(state.params), opt_state=zero(state.opt_state))
  staged = checkpointing.checkpoint_manager(staging)
  staged.save(step, args=ocp.args.StandardSave(state))
  staged.wait_until_finished()
  os.makedirs(out, exist_ok=True)
  path = os.path.join(out, f'{name}.tgz')
  with tarfile.open(path, 'w:gz') as t:
    t.add(staging, arcname=name)
  shutil.rmtree(tmp)
  print(f'{name}: step {step}, {os.path.getsize(path) / 2**20:.1f} MiB', flush=True)
  return path


def define_flags() -> None:
  """The mode's flags (defined on use only: tests import `pack` beside other modules' flags)."""
  flags.DEFINE_string('out', None, 'Folder for NAME.tgz, one per run.')
  flags.DEFINE_multi_string('workdir', [], 'A run directory to pack (repeat for several).')
  flags.mark_flags_as_required(['out'])


def main(argv):
  from ld_mpc_jax.cli import errors as cli
  workdirs = flags.FLAGS.workdir
  with cli.one_line_errors():
    if argv[1:]:
      raise ValueError(f'name runs with --workdir=, not positionally: {" ".join(argv[1:])}')
    missing = [w for w in workdirs if not os.path.isdir(w)]
    if not workdirs or missing:
      raise FileNotFoundError(f'no run directory {missing[0]}' if missing else
                              'name the run directories to pack (--workdir=RUN, repeated)')
  for workdir in workdirs:
    if pack(workdir, flags.FLAGS.out) is None:
      print(f'{os.path.basename(os.path.normpath(workdir))}: no checkpoint')
