"""Orbax checkpoints of the TrainState, with the config saved beside them."""

import contextlib
import errno
import glob
import json
import logging
import os
import re
import shutil
import sys
import threading
from typing import Callable, Iterator, List, Optional, Tuple, Union

import jax
import ml_collections
import orbax.checkpoint as ocp

from ld_mpc_jax import configs
from ld_mpc_jax.ops import legacy
from ld_mpc_jax.learn.train_state import (LearnSettings, TrainState, check_settings,
                                          create_train_state)

CONFIG_FILE = 'config.json'
def legacy_defaults() -> dict:
  """What a config saved before a field existed is read with ({section: {field: value}}).

  Such a value changes nothing against the code before the field (evaluation_suite drops fields
  at these values from its cache keys, so adding a field does not invalidate cached cells).
  Changing a value already in these tables moves cached cells to another config's key: raise
  evaluation_suite.CACHE_VERSION with it.
  """
  return legacy.neutral_values()


def checkpoint_manager(workdir: str, max_to_keep: int = 3) -> ocp.CheckpointManager:
  """Synchronous manager under <workdir>/checkpoints (a step is visible only once complete)."""
  options = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True,
                                         enable_async_checkpointing=False)
  return ocp.CheckpointManager(os.path.abspath(os.path.join(workdir, 'checkpoints')),
                               options=options)


def has_checkpoint(workdir: str) -> bool:
  """Whether `workdir` holds a complete checkpoint (creates nothing)."""
  return (os.path.isdir(os.path.join(workdir, 'checkpoints'))
          and checkpoint_manager(workdir).latest_step() is not None)


def save_config(config: Union[ml_collections.ConfigDict, str], workdir: str) -> str:
  """Writes config.json: `config`'s JSON, or `config` itself, that JSON (SeedPlan.config_json)."""
  os.makedirs(workdir, exist_ok=True)
  path = os.path.join(workdir, CONFIG_FILE)
  with open(path + '.tmp', 'w') as f:
    f.write(config if isinstance(config, str) else config.to_json_best_effort(indent=2))
  os.replace(path + '.tmp', path)
  return path


class WorkdirError(ValueError):
  """A workdir this run must not or cannot write to (made with another config, all of its
  checkpoints damaged, its disk full): one line, exit code 2."""


class DiskFullError(WorkdirError):
  """A write into the workdir failed for want of space; the checkpoints before it are kept."""


_FULL = ('No space left on device', 'Disk quota exceeded')


def disk_full(err: BaseException) -> bool:
  """Whether `err` is a write that failed for want of space: an OSError (ENOSPC, EDQUOT), or
  tensorstore's error (orbax raises it as a ValueError naming the OS error)."""
  if isinstance(err, DiskFullError):
    return False  # Reported already.
  if isinstance(err, OSError) and err.errno in (errno.ENOSPC, errno.EDQUOT):
    return True
  return any(text in str(err) for text in _FULL)


def complete_steps(workdir: str) -> List[int]:
  """The checkpoint steps under <workdir>/checkpoints whose write finished (read only)."""
  folder = os.path.join(workdir, 'checkpoints')
  return sorted(int(n) for n in os.listdir(folder) if n.isdigit()) if os.path.isdir(folder) else []


@contextlib.contextmanager
def stop_when_disk_full(workdir: str) -> Iterator[None]:
  """Turns a write that failed for want of space inside the block into one line
  (DiskFullError) naming the full disk and the checkpoint a rerun resumes from.

  The log records orbax's writer threads and asyncio emit about the same failed write (dozens
  of tracebacks, some at exit) are dropped, from here on: the one line says it.
  """
  _quiet_disk_full_logs()
  _quiet_abandoned_reads()  # A failed write's abandoned tensorstore callbacks, as a restore's.
  try:
    yield
  except Exception as err:  # pylint: disable=broad-except (orbax: ValueError; Python: OSError)
    if not disk_full(err):
      raise
    _quiet_after_disk_full()
    raise DiskFullError(disk_full_message(workdir, _failed_write(err))) from None


def kept_checkpoint(workdir: str) -> Tuple[Optional[int], str]:
  """(the newest checkpoint step every seed of the run in `workdir` has complete, or None; the
  checkpoints folder to name: <workdir>/checkpoints, or <workdir>/seed*/checkpoints)."""
  folders = ([workdir] if os.path.isdir(os.path.join(workdir, 'checkpoints')) else
             sorted(glob.glob(os.path.join(workdir, 'seed*'))))
  common = set.intersection(*[set(complete_steps(f)) for f in folders]) if folders else set()
  shown = os.path.join(workdir if folders == [workdir] else os.path.join(workdir, 'seed*'),
                       'checkpoints')
  return (max(common) if common else None), shown


def disk_full_message(workdir: str, where: Optional[str]) -> str:
  """The one line of a full disk: the file whose write failed (relative to `workdir` when in it),
  and the checkpoint the same command resumes from (every seed's, for <workdir>/seed<n>/)."""
  step, shown = kept_checkpoint(workdir)
  kept = (f'checkpoint step {step} and those before it are kept in {shown}; free some '
          'space and rerun the same command to resume from it' if step is not None else
          'no checkpoint was written yet; free some space and rerun the same command')
  inside = where and os.path.abspath(where).startswith(os.path.abspath(workdir) + os.sep)
  disk = (f'the device of {workdir} (writing {os.path.relpath(where, workdir)})' if inside else
          f'the device (writing {where})' if where else f'the device of {workdir}')
  return f'no space left on {disk}: {kept}'


def _quiet_after_disk_full() -> None:
  """After the one line, what the full disk still breaks at exit says nothing more:
  tensorboardX's atexit flush (an unraisable disk-full OSError), then its writer thread (an
  OSError: the queue that failed flush left open is closed under it). Installed once."""
  if getattr(sys.unraisablehook, 'quiet_disk_full', False):
    return
  previous, previous_thread = sys.unraisablehook, threading.excepthook
  def hook(unraisable):
    if not disk_full(unraisable.exc_value):
      previous(unraisable)
  def thread_hook(args):
    if not issubclass(args.exc_type, OSError):
      previous_thread(args)
  hook.quiet_disk_full = True
  sys.unraisablehook, threading.excepthook = hook, thread_hook


def _failed_write(err: BaseException) -> Optional[str]:
  """The file whose write failed, as `err` names it (OSError's filename, tensorstore's text)."""
  if isinstance(err, OSError) and err.filename:
    return str(err.filename)
  found = re.search(r'Failed writing: "([^"]+)"', str(err))
  return found.group(1) if found else None


def _about_full_disk(record: logging.LogRecord) -> bool:
  error = record.exc_info[1] if record.exc_info else None
  try:
    text = record.getMessage()
  except Exception:  # pylint: disable=broad-except (a record with bad arguments: keep it)
    text = ''
  return (error is not None and disk_full(error)) or any(t in text for t in _FULL)


def _quiet_disk_full_logs() -> None:
  """Drops log records about a full disk from orbax (absl's logger) and asyncio; once."""
  for name in ('absl', 'asyncio'):
    logger = logging.getLogger(name)
    if not any(getattr(f, 'quiet_disk_full', False) for f in logger.filters):
      keep = lambda record: not _about_full_disk(record)
      keep.quiet_disk_full = True
      logger.addFilter(keep)


def remove_partial(manager: ocp.CheckpointManager, step: int) -> None:
  """Removes what a failed write of `step` left (orbax's temporary folders), giving its space
  back; the finished steps stay."""
  folder = str(manager.directory)
  for name in os.listdir(folder) if os.path.isdir(folder) else []:
    if name.startswith(f'{step}.orbax-checkpoint-tmp'):
      shutil.rmtree(os.path.join(folder, name), ignore_errors=True)


def _flat(tree: dict) -> dict:
  """{'section.field': value} of a config as nested dicts, as JSON (tuples and lists alike)."""
  out = {}
  def walk(node, prefix):
    for k, v in node.items():
      if isinstance(v, dict):
        walk(v, f'{prefix}{k}.')
      else:
        out[prefix + k] = v
  walk(json.loads(json.dumps(tree, default=str)), '')
  return out


# Where a run computes, not what: a run continues under another value without
# --continue_with_changes (the seeds over devices give the same parameters to float tolerance).
PLACEMENT_FIELDS = ('train.seed_devices',)


def config_changes(saved: dict, current: dict) -> List[str]:
  """'field (old -> new)' for every field whose value differs between two configs as nested
  dicts (ConfigDict.to_dict()), sorted by name, but the `PLACEMENT_FIELDS`; a field only one side
  has shows as absent. `saved` is compared as loaded (`migrate_config`)."""
  old, new = _flat(saved), _flat(current)
  for k in PLACEMENT_FIELDS:
    old.pop(k, None), new.pop(k, None)
  show = lambda flat, k: json.dumps(flat[k]) if k in flat else 'absent'
  return [f'{k} ({show(old, k)} -> {show(new, k)})' for k in sorted(set(old) | set(new))
          if k not in old or k not in new or old[k] != new[k]]


def check_workdir(fields: dict, learn: LearnSettings, workdir: str,
                  continue_with_changes: bool = False) -> None:
  """WorkdirError when `workdir` holds a run of another config (`fields`: as the run records it,
  nested dicts; `learn`: its LearnSettings); reads, never writes. With `continue_with_changes`, a
  changed config continues the run, unless its networks no longer fit the checkpoint."""
  if not os.path.exists(os.path.join(workdir, CONFIG_FILE)):
    return
  saved = load_config(workdir)
  changes = config_changes(saved.to_dict(), fields)
  if not changes:
    return
  if not continue_with_changes:
    shown = ', '.join(changes[:6]) + (f' and {len(changes) - 6} more' if len(changes) > 6 else '')
    raise WorkdirError(f'{workdir} holds a run of another config; this one differs in {shown}: '
                       'choose another --workdir, or pass --continue_with_changes to continue '
                       'that run under this config')
  shapes = lambda s: jax.tree.map(lambda x: x.shape, abstract_state(s))
  if has_checkpoint(workdir) and shapes(LearnSettings.from_config(saved)) != shapes(learn):
    raise WorkdirError(f'{workdir}: even with --continue_with_changes, its checkpoints cannot '
                       f'continue under this config: the networks differ ({", ".join(changes)})')
  if 'online' in saved and 'online' in fields:
    _warn_moved_schedules(configs.schedule_end(saved.online), configs.schedule_end(fields['online']))


def _warn_moved_schedules(old: int, new: int) -> None:
  """Warns, in one line, when a continued online run's annealed schedules (configs.schedule_end:
  `online.schedule_steps`, or `online.env_steps`) would end at `new` steps, not its own `old`."""
  if old != new:
    _warn(f'the annealed schedules (demonstrations\' share, executed-action noise, '
          f'act_schedule=linear) of this run ended at {old} simulator steps and now end at {new}; '
          f'--config.online.schedule_steps={old} keeps the run\'s')


def record_config(config: Union[ml_collections.ConfigDict, str], workdir: str) -> str:
  """Saves config.json (`save_config`); a different earlier one is kept as config.<n>.json."""
  path, current = os.path.join(workdir, CONFIG_FILE), (
      json.loads(config) if isinstance(config, str) else config.to_dict())
  if os.path.exists(path) and config_changes(load_config(workdir).to_dict(), current):
    n = 1
    while os.path.exists(os.path.join(workdir, f'config.{n}.json')):
      n += 1
    os.replace(path, os.path.join(workdir, f'config.{n}.json'))
  return save_config(config, workdir)


def load_config(workdir: str) -> ml_collections.ConfigDict:
  path = os.path.join(workdir, CONFIG_FILE)
  if not os.path.exists(path):
    raise FileNotFoundError(f'no {CONFIG_FILE} in {workdir}: is it a training workdir?')
  try:
    with open(path, encoding='utf-8') as f:
      raw = json.load(f)
  except (UnicodeDecodeError, json.JSONDecodeError) as err:
    raise WorkdirError(f'{path} is damaged (not JSON: {err}); put back a good copy, or move '
                       'the workdir aside and start the run again') from None
  if not isinstance(raw, dict):
    raise WorkdirError(f'{path} is damaged (holds a {type(raw).__name__}, not a config); put '
                       'back a good copy, or move the workdir aside and start the run again')
  return migrate_config(raw)


def migrate_config(saved: dict) -> ml_collections.ConfigDict:
  """The ConfigDict of a saved config (a loaded config.json as nested dicts, left as it is) brought
  up to the current version, once, on load (legacy.migrate): fields added since it was saved get
  the values that mean what its run did; renamed sections get their new name (`objective` ->
  `critic`); a config of a newer version is refused on one line. Sequence fields saved as JSON
  lists stay lists; the library reads them only as sequences."""
  return ml_collections.ConfigDict(legacy.migrate(saved))


def abstract_state(settings: LearnSettings) -> TrainState:
  """Shapes, dtypes and placement of a TrainState, without allocating it (restore target).

  Placed on this process's first device: without a placement orbax takes the one saved with the
  checkpoint, and a checkpoint written on a GPU then refuses to load on a CPU ("Topology
  mismatch"). Data-parallel runs replicate the restored state themselves.
  """
  check_settings(settings, 'abstract_state')
  shapes = jax.eval_shape(lambda: create_train_state(settings, jax.random.key(0)))
  here = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
  return jax.tree.map(lambda s: jax.ShapeDtypeStruct(s.shape, s.dtype, sharding=here), shapes)


def _warn(message: str) -> None:
  print(f'warning: {message}', file=sys.stderr)


def _one_line(err: BaseException, limit: int = 300) -> str:
  text = ' '.join(f'{type(err).__name__}: {err}'.split()).split(' See full TensorStore')[0]
  return text if len(text) <= limit else text[:limit - 3] + '...'


def _quiet_abandoned_reads() -> None:
  """Drops the noise a failed orbax restore leaves: its other tensorstore reads finish after
  asyncio's loop closed (hundreds of 'Event loop is closed' tracebacks, and 'exception was never
  retrieved' log lines of asyncio). Installed once, after a restore failed or as a run starts
  (`stop_when_disk_full`: a failed write leaves the same)."""
  if getattr(sys.unraisablehook, 'quiet_abandoned_reads', False):
    return
  previous = sys.unraisablehook
  def hook(unraisable):
    if not (unraisable.exc_type is RuntimeError
            and str(unraisable.exc_value) == 'Event loop is closed'):
      previous(unraisable)
  hook.quiet_abandoned_reads = True
  sys.unraisablehook = hook
  logging.getLogger('asyncio').addFilter(
      lambda record: 'exception was never retrieved' not in record.getMessage())


def restore_intact(manager: ocp.CheckpointManager, target: TrainState,
                   usable: Optional[Callable[[int], Optional[str]]] = None,
                   ) -> Tuple[Optional[int], Optional[TrainState], List[int]]:
  """(step, state, skipped): the newest checkpoint that restores into `target` (the state's
  shapes, dtypes and placement: `abstract_state`), newest first.

  A step whose files fail to restore (damaged or truncated), or for which `usable(step)` gives
  a reason (e.g. an online run's missing buffer file), is skipped with one warning line naming
  it and why; `skipped` lists those steps. (None, None, []) without any checkpoint; WorkdirError
  when every step was skipped.
  """
  skipped = []
  for step in sorted(manager.all_steps(), reverse=True):
    reason = usable(step) if usable is not None else None
    if reason is None:
      try:
        state = manager.restore(step, args=ocp.args.StandardRestore(target))
      except Exception as err:  # pylint: disable=broad-except (orbax/tensorstore: many kinds)
        reason = _one_line(err)
        _quiet_abandoned_reads()
      else:
        return step, state, skipped
    _warn(f'checkpoint step {step} in {manager.directory} skipped, {reason}; trying an '
          'earlier one')
    skipped.append(step)
  if skipped:
    raise WorkdirError(no_intact_message(str(manager.directory), skipped))
  return None, None, []


def no_intact_message(directory: str, skipped: List[int]) -> str:
  """The one line when every checkpoint step under `directory` failed: which, and what to do
  (the damaged steps are left where they are: only the user decides to drop a run)."""
  steps = (f'step {skipped[0]} failed' if len(skipped) == 1 else
           f'steps {", ".join(map(str, skipped))} all failed')
  return (f'no intact checkpoint in {directory}: {steps} (warnings above). To start this run '
          f'over, move that folder aside (mv {directory} {directory}.damaged) and rerun the '
          'training command; or train into another --workdir')


def set_aside(workdir: str, manager: ocp.CheckpointManager, steps: List[int]) -> None:
  """Moves checkpoint `steps` to <workdir>/damaged_checkpoints/<step> (kept, out of the way of
  the steps a resumed run saves again), then reloads the manager."""
  for step in steps:
    target = os.path.join(workdir, 'damaged_checkpoints', str(step))
    shutil.rmtree(target, ignore_errors=True)
    os.makedirs(os.path.dirname(target), exist_ok=True)
    os.replace(os.path.join(str(manager.directory), str(step)), target)
  if steps:
    manager.reload()


def restore_latest(manager: ocp.CheckpointManager, target: TrainState) -> Optional[TrainState]:
  """The newest intact checkpoint restored into `target` (`restore_intact`), or None."""
  return restore_intact(manager, target)[1]


def load_for_evaluation(workdir: str, check: Optional[Callable] = None):
  """(config, ema_params, step) from a workdir's config and newest intact checkpoint (a newer
  damaged one skipped with a warning line, left as it is); `check(config)` (check_config; the
  commands: runs.checks.validate_config) refuses a hand-edited config before any is read."""
  config = load_config(workdir)
  if check is None:
    from ld_mpc_jax.model.config_checks import check_config as check  # pylint: disable=g-import-not-at-top
  try:  # A hand-edited config is its own fault, not the checkpoints'.
    check(config)
  except ValueError as err:
    raise WorkdirError(f'{os.path.join(workdir, CONFIG_FILE)} is not a valid config ({err}); '
                       'undo the edit (the checkpoints were not read)') from None
  folder = os.path.join(workdir, 'checkpoints')  # Not made by a manager when it is missing:
  state = None if not os.path.isdir(folder) else restore_latest(
      checkpoint_manager(workdir), abstract_state(LearnSettings.from_config(config)))
  if state is None:
    raise FileNotFoundError(f'no checkpoint under {folder}')
  return config, state.ema_params, int(state.step)
