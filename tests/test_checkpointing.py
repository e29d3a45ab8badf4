"""ld_mpc_jax.learn.checkpointing: configs saved before a field existed load with the value their run
used (migrate_config), so library code reads fields directly; checkpoints come back bit for bit,
onto this process's device whatever device wrote them."""

import json
import os
import sys
import threading

import jax
import numpy as np
import orbax.checkpoint as ocp
import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.configs import door_open_online
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.runs.checks import validate_config
from ld_mpc_jax.runs.seed_plan import seed_plans
from ld_mpc_jax.learn.train_state import LearnSettings, create_train_state

# Fields whose fallbacks moved into migrate_config, with what a run saved before them did.
OLD_RUN_VALUES = {
    ('data', 'source'): 'metaworld', ('data', 'path'): '',
    ('data', 'max_episode_steps'): 500, ('train', 'data_parallel'): False,
    ('eval', 'data_parallel'): False, ('model', 'normalize_obs'): False,
    ('model', 'task_dim'): 96,
}


@pytest.mark.parametrize('section,name', sorted(OLD_RUN_VALUES))
def test_old_config_without_the_field_loads_with_its_run_value(tmp_path, section, name):
  raw = json.loads(door_open.get_config('smoke').to_json_best_effort())
  del raw['version']  # Saved before configs had a version (version 0).
  del raw[section][name]
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  config = checkpointing.load_config(str(tmp_path))
  assert config[section][name] == OLD_RUN_VALUES[section, name]


@pytest.mark.parametrize('safe', [False, True])
def test_old_online_run_acted_with_its_plan_selection(tmp_path, safe):
  from ld_mpc_jax.configs import door_open_online
  raw = json.loads(door_open_online.get_config('smoke').to_json_best_effort())
  del raw['version']  # Saved before configs had a version (version 0).
  raw['plan']['safe_selection'] = safe
  del raw['online']['act_safe_selection']  # Saved before acting had its own selection.
  del raw['online']['train_goals']  # Saved when training always used the MT1 seed's 50 goals.
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  loaded = checkpointing.load_config(str(tmp_path))
  assert loaded.online.act_safe_selection is safe and loaded.online.train_goals == 'mt1'


def test_old_online_run_searched_while_acting_as_it_evaluated(tmp_path):
  from ld_mpc_jax.configs import door_open_online
  raw = json.loads(door_open_online.get_config('cpu').to_json_best_effort())
  del raw['version']  # Saved before configs had a version (version 0).
  raw['plan']['num_gaussian'], raw['plan']['iterations'] = 16, 2
  del raw['online']['act_num_gaussian'], raw['online']['act_iterations']
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  loaded = checkpointing.load_config(str(tmp_path))
  assert (loaded.online.act_num_gaussian, loaded.online.act_iterations) == (16, 2)


def test_saved_config_round_trips(tmp_path):
  config = door_open.get_config('smoke')
  checkpointing.save_config(config, str(tmp_path))
  loaded = checkpointing.load_config(str(tmp_path))
  assert json.loads(loaded.to_json_best_effort()) == json.loads(config.to_json_best_effort())


def test_old_run_values_do_not_follow_todays_defaults(tmp_path, monkeypatch):
  """Most of the old runs' values are also today's defaults; a migration that filled today's
  defaults would pass the test above. With every one of these defaults changed in base.py, a
  config saved without the fields still loads with what the old runs used."""
  from ld_mpc_jax.configs import base
  other = lambda v: (not v) if isinstance(v, bool) else v + 1 if isinstance(v, int) else v + 'x'
  make_base = base.get_config

  def changed_base():
    c = make_base()
    for section, name in OLD_RUN_VALUES:
      c[section][name] = other(c[section][name])
    return c

  raw = json.loads(door_open.get_config('smoke').to_json_best_effort())
  del raw['version']  # Saved before configs had a version (version 0).
  for section, name in OLD_RUN_VALUES:
    del raw[section][name]
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  monkeypatch.setattr(base, 'get_config', changed_base)
  assert door_open.get_config('smoke').data.source != OLD_RUN_VALUES['data', 'source']
  config = checkpointing.load_config(str(tmp_path))
  assert {k: config[k[0]][k[1]] for k in OLD_RUN_VALUES} == OLD_RUN_VALUES


def test_saved_values_are_kept_not_migrated(tmp_path):
  """Migration fills only absent fields: a saved field keeps its value, also where the value
  differs from both today's default and the old runs' value."""
  raw = json.loads(door_open.get_config('smoke').to_json_best_effort())
  saved = dict(data=dict(source='tdmpc2', path='d.npz', max_episode_steps=200),
               train=dict(data_parallel=True, num_seeds=3), eval=dict(batch_size=7, seeds=[4]),
               plan=dict(pessimism=2.5, safe_selection=True, safe_margin=3.0),
               model=dict(normalize_obs=False, task_dim=12))
  for section, fields in saved.items():
    raw[section].update(fields)
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  config = checkpointing.load_config(str(tmp_path))
  assert json.loads(config.to_json_best_effort()) == raw


def test_a_checkpoint_round_trip_returns_the_same_state(tmp_path):
  """Every leaf (parameters, Adam moments and counts, EMA, step), each made to differ from a
  fresh state's, comes back bit for bit, with its dtype; so do the config and the EMA parameters
  evaluation reads."""
  import chex
  config = door_open.get_config('smoke')
  learn = LearnSettings.from_config(config)
  fresh = create_train_state(learn, jax.random.key(3))
  rng = np.random.default_rng(4)
  move = lambda x: x + (7 if np.issubdtype(x.dtype, np.integer)
                        else rng.standard_normal(x.shape).astype(x.dtype))
  state = jax.device_put(jax.tree.map(move, jax.device_get(fresh)))
  checkpointing.save_config(config, str(tmp_path))
  manager = checkpointing.checkpoint_manager(str(tmp_path))
  manager.save(int(state.step), args=ocp.args.StandardSave(state))
  manager.wait_until_finished()
  restored = checkpointing.restore_latest(checkpointing.checkpoint_manager(str(tmp_path)),
                                          checkpointing.abstract_state(learn))
  chex.assert_trees_all_equal(restored, state, strict=True)
  loaded, ema_params, step = checkpointing.load_for_evaluation(str(tmp_path))
  chex.assert_trees_all_equal(ema_params, state.ema_params, strict=True)
  assert step == int(fresh.step) + 7
  assert json.loads(loaded.to_json_best_effort()) == json.loads(config.to_json_best_effort())


def test_old_objective_section_is_migrated_to_critic(tmp_path):
  """Runs saved before the rename kept the critic settings under `objective`: on load they move,
  values kept, to `critic`, and no `objective` section is left."""
  raw = json.loads(door_open.get_config('smoke').to_json_best_effort())
  del raw['version']  # Saved before configs had a version (version 0).
  raw['objective'] = dict(raw.pop('critic'), td_target='policy', num_values=4, hidden=[8])
  (tmp_path / checkpointing.CONFIG_FILE).write_text(json.dumps(raw))
  config = checkpointing.load_config(str(tmp_path))
  assert 'objective' not in config
  assert config.critic.to_dict() == raw['objective']
  validate_config(config)


def test_a_config_with_an_objective_section_is_refused_naming_critic():
  """Only a saved config is migrated (on load); one built with the old name is an error."""
  config = door_open.get_config('smoke')
  config.unlock()
  config.objective = config.critic
  del config['critic']
  with pytest.raises(ValueError, match='config.objective is now config.critic'):
    validate_config(config)
  with pytest.raises(ValueError, match="'objective.hidden'.*now config.critic"):
    with_overrides(door_open.get_config('smoke'), {'objective.hidden': (8,)})


def test_a_checkpoint_written_on_another_backend_restores_here(tmp_path):
  """A run trained on a GPU is evaluated on a laptop: the saved placement ("cuda:0") is not
  this machine's, and the state still restores, onto this process's device, values intact."""
  learn = LearnSettings.from_config(door_open.get_config('smoke'))
  state = create_train_state(learn, jax.random.key(3))
  manager = checkpointing.checkpoint_manager(str(tmp_path))
  manager.save(7, args=ocp.args.StandardSave(state))
  manager.wait_until_finished()
  placement = tmp_path / 'checkpoints' / '7' / 'default' / '_sharding'
  saved = placement.read_text()
  assert '"cpu:0"' in saved.replace('\\"', '"')
  placement.write_text(saved.replace('cpu:0', 'cuda:0'))
  restored = checkpointing.restore_latest(checkpointing.checkpoint_manager(str(tmp_path)),
                                          checkpointing.abstract_state(learn))
  assert int(restored.step) == int(state.step)
  for a, b in zip(jax.tree.leaves(restored.ema_params), jax.tree.leaves(state.ema_params)):
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert a.devices() == {jax.local_devices()[0]}


def _check_workdir(config, workdir, continue_with_changes=False):
  """checkpointing.check_workdir of a config's recorded fields and LearnSettings."""
  checkpointing.check_workdir(config.to_dict(), LearnSettings.from_config(config), workdir,
                              continue_with_changes)


def test_a_workdir_of_another_config_is_refused_naming_the_fields(tmp_path):
  workdir = str(tmp_path)
  saved = door_open.get_config('smoke')
  checkpointing.save_config(saved, workdir)
  _check_workdir(door_open.get_config('smoke'), workdir)  # The same: no error.
  other = with_overrides(door_open.get_config('smoke'), {'train.learning_rate': 1e-2, 'seed': 7})
  with pytest.raises(checkpointing.WorkdirError) as err:
    _check_workdir(other, workdir)
  message = str(err.value)
  assert '\n' not in message and '--continue_with_changes' in message
  assert f'seed (0 -> 7), train.learning_rate ({saved.train.learning_rate} -> 0.01)' in message
  _check_workdir(other, workdir, continue_with_changes=True)  # No checkpoint.
  assert os.listdir(workdir) == [checkpointing.CONFIG_FILE]  # Checks write nothing.
  # Where the seeds compute is no change: a run continues on other devices as it is.
  placed = with_overrides(door_open.get_config('smoke'), {'train.seed_devices': 3})
  assert saved.train.seed_devices != 3
  _check_workdir(placed, workdir)
  assert checkpointing.config_changes(saved.to_dict(), placed.to_dict()) == []


def test_continuing_with_other_networks_is_refused_even_with_the_flag(tmp_path):
  workdir = str(tmp_path)
  config = door_open.get_config('smoke')
  checkpointing.save_config(config, workdir)
  manager = checkpointing.checkpoint_manager(workdir)
  state = create_train_state(LearnSettings.from_config(config), jax.random.key(0))
  manager.save(1, args=ocp.args.StandardSave(state))
  manager.wait_until_finished()
  wider = with_overrides(door_open.get_config('smoke'), {'model.width': 32})
  with pytest.raises(checkpointing.WorkdirError, match=r'networks differ \(model.width'):
    _check_workdir(wider, workdir, continue_with_changes=True)


def test_continuing_to_more_steps_warns_that_the_schedules_move(tmp_path, capsys):
  workdir = str(tmp_path)
  checkpointing.save_config(door_open_online.get_config('smoke'), workdir)
  longer = door_open_online.get_config('smoke')
  longer.online.env_steps *= 2
  _check_workdir(longer, workdir, continue_with_changes=True)
  err = capsys.readouterr().err.strip()
  old = longer.online.env_steps // 2
  assert err.count('\n') == 0 and err.endswith(f'--config.online.schedule_steps={old} keeps the run\'s')
  longer.online.schedule_steps = old  # Kept: nothing to say.
  _check_workdir(longer, workdir, continue_with_changes=True)
  assert capsys.readouterr().err == ''


def test_a_changed_config_keeps_the_earlier_one_beside_it(tmp_path):
  workdir = str(tmp_path)
  first = door_open.get_config('smoke')
  checkpointing.record_config(first, workdir)
  checkpointing.record_config(first, workdir)  # The same config: nothing kept.
  assert sorted(os.listdir(workdir)) == [checkpointing.CONFIG_FILE]
  checkpointing.record_config(with_overrides(first, {'seed': 3}), workdir)
  assert sorted(os.listdir(workdir)) == ['config.1.json', checkpointing.CONFIG_FILE]
  assert json.load(open(tmp_path / 'config.1.json'))['seed'] == 0
  assert checkpointing.load_config(workdir).seed == 3


def _two_checkpoints(workdir):
  """A workdir of the smoke config with checkpoints at steps 1 and 2; step 2's data files
  truncated to half. Returns the config."""
  config = door_open.get_config('smoke')
  checkpointing.save_config(config, workdir)
  manager = checkpointing.checkpoint_manager(workdir)
  state = create_train_state(LearnSettings.from_config(config), jax.random.key(0))
  for step in (1, 2):
    manager.save(step, args=ocp.args.StandardSave(state.replace(step=step)))
  manager.wait_until_finished()
  _truncate(workdir, 2)
  return config


def _truncate(workdir, step):
  """Truncates every array data file of checkpoint `step` to half (one alone may hold nothing
  restore reads)."""
  for root, _, names in os.walk(os.path.join(workdir, 'checkpoints', str(step), 'default')):
    for name in names:
      if os.path.basename(root) == 'd':
        path = os.path.join(root, name)
        with open(path, 'r+b') as f:
          f.truncate(os.path.getsize(path) // 2)


def test_a_damaged_checkpoint_falls_back_to_the_newest_intact_one(tmp_path, capsys):
  workdir = str(tmp_path)
  _two_checkpoints(workdir)
  _, _, step = checkpointing.load_for_evaluation(workdir)  # Evaluation: read only.
  assert step == 1
  warning = capsys.readouterr().err.strip().splitlines()
  assert len(warning) == 1 and warning[0].startswith('warning: checkpoint step 2 in ')
  assert 'skipped' in warning[0] and 'trying an earlier one' in warning[0]
  # The failed restore's abandoned reads stay quiet ('Event loop is closed', hundreds of times).
  assert getattr(sys.unraisablehook, 'quiet_abandoned_reads', False)
  assert checkpointing.checkpoint_manager(workdir).all_steps() == [1, 2]


def test_a_resumed_run_sets_damaged_steps_aside_and_saves_them_again(tmp_path):
  from ld_mpc_jax.runs import loop as runs
  workdir = str(tmp_path)
  config = _two_checkpoints(workdir)
  run = runs.Run(seed_plans(config, workdir)[0])
  state = run.restore()
  assert (run.step, int(state.step)) == (1, 1)
  assert run.manager.all_steps() == [1]
  assert os.listdir(tmp_path / 'damaged_checkpoints') == ['2']
  run.save(state.replace(step=2), 2, 0.0)  # Step 2 is saved again, not silently skipped.
  assert run.manager.all_steps() == [1, 2]


def test_a_step_without_what_the_run_needs_is_skipped(tmp_path):
  workdir = str(tmp_path)
  learn = LearnSettings.from_config(door_open.get_config('smoke'))
  manager = checkpointing.checkpoint_manager(workdir)
  state = create_train_state(learn, jax.random.key(0))
  for step in (1, 2):
    manager.save(step, args=ocp.args.StandardSave(state))
  manager.wait_until_finished()
  target = checkpointing.abstract_state(learn)
  step, _, skipped = checkpointing.restore_intact(
      manager, target, lambda s: 'no buffer_2.npz' if s == 2 else None)
  assert (step, skipped) == (1, [2])
  with pytest.raises(checkpointing.WorkdirError, match='no intact checkpoint .* steps 2, 1 all'):
    checkpointing.restore_intact(manager, target, lambda s: 'no buffer file')
  alone = checkpointing.checkpoint_manager(os.path.join(workdir, 'one'))
  alone.save(2, args=ocp.args.StandardSave(state))
  alone.wait_until_finished()
  with pytest.raises(checkpointing.WorkdirError, match=r'no intact checkpoint .*: step 2 failed '):
    checkpointing.restore_intact(alone, target, lambda s: 'no buffer file')


def test_every_checkpoint_damaged_stops_on_one_line_that_says_what_to_do(tmp_path):
  from ld_mpc_jax.eval import run_files
  from ld_mpc_jax.runs import loop as runs
  workdir = str(tmp_path)
  config = _two_checkpoints(workdir)
  _truncate(workdir, 1)
  run_files.append_csv(str(tmp_path / runs.EVAL_CSV), {'step': 2, 'success_rate': 0.5})
  folder = os.path.join(workdir, 'checkpoints')
  for attempt in (lambda: checkpointing.load_for_evaluation(workdir),
                  lambda: runs.Run(seed_plans(config, workdir)[0]).restore()):
    with pytest.raises(checkpointing.WorkdirError) as err:
      attempt()
    line = str(err.value)
    assert '\n' not in line and line.startswith(f'no intact checkpoint in {folder}: steps 2, 1')
    assert f'move that folder aside (mv {folder} {folder}.damaged) and rerun' in line
    assert line.endswith('or train into another --workdir')
  assert checkpointing.checkpoint_manager(workdir).all_steps() == [1, 2]  # Left as they were.
  os.rename(folder, folder + '.damaged')  # As the line says: the run starts over, its old log
  run = runs.Run(seed_plans(config, workdir)[0])  # rows gone (not repeated by the new run).
  assert run.restore() is None and run.step is None
  assert run_files.read_csv(str(tmp_path / runs.EVAL_CSV)) == []


def test_a_full_disk_during_a_checkpoint_write_stops_on_one_line_keeping_the_last(
    tmp_path, monkeypatch):
  import errno
  monkeypatch.setattr(sys, 'unraisablehook', sys.unraisablehook)  # As they were, after it.
  monkeypatch.setattr(threading, 'excepthook', threading.excepthook)
  from ld_mpc_jax.runs import loop as runs
  workdir = str(tmp_path)
  config = door_open.get_config('smoke')
  run = runs.Run(seed_plans(config, workdir)[0])
  learn = LearnSettings.from_config(config)
  state = create_train_state(learn, jax.random.key(0))
  run.save(state.replace(step=1), 1, 0.0)
  folder = os.path.join(workdir, 'checkpoints')

  def full_disk(step, args):  # Orbax writes into a temporary folder, then the disk fills.
    os.makedirs(os.path.join(folder, f'{step}.orbax-checkpoint-tmp-7', 'default'))
    raise OSError(errno.ENOSPC, 'No space left on device', os.path.join(folder, 'x'))
  monkeypatch.setattr(run.manager, 'save', full_disk)
  with pytest.raises(checkpointing.DiskFullError) as err:
    with checkpointing.stop_when_disk_full(workdir):
      run.save(state.replace(step=2), 2, 1.0)
  assert isinstance(err.value, checkpointing.WorkdirError)  # The launcher: one line, exit 2.
  assert str(err.value) == (
      f'no space left on the device of {workdir} (writing checkpoints/x): checkpoint step 1 and '
      f'those before it are kept in {folder}; free some space and rerun the same command to '
      'resume from it')
  assert sorted(os.listdir(folder)) == ['1']  # No partial step 2 left to be picked up.
  assert json.load(open(tmp_path / 'progress.json'))['step'] == 1
  step, restored, skipped = checkpointing.restore_intact(
      checkpointing.checkpoint_manager(workdir), checkpointing.abstract_state(learn))
  assert (step, skipped) == (1, [])
  same = jax.tree.map(lambda a, b: np.array_equal(a, b), restored, state.replace(step=1))
  assert all(jax.tree_util.tree_leaves(same))


@pytest.mark.parametrize('error,full', [
    (OSError(28, 'No space left on device'), True),
    (ValueError('RESOURCE_EXHAUSTED: Failed writing: "/w/c/2.orbax-checkpoint-tmp/d/ab": Failed '
                "to write 12 bytes to file 19: No space left on device [os_error_code='28']"),
     True),
    (PermissionError(13, 'Permission denied'), False), (ValueError('bad'), False)])
def test_only_a_full_disk_becomes_the_one_line(tmp_path, monkeypatch, error, full):
  monkeypatch.setattr(sys, 'unraisablehook', sys.unraisablehook)  # As they were, after it.
  monkeypatch.setattr(threading, 'excepthook', threading.excepthook)
  def fail():
    with checkpointing.stop_when_disk_full(str(tmp_path)):
      raise error
  with pytest.raises(checkpointing.DiskFullError if full else type(error)) as got:
    fail()
  if full:
    assert str(got.value).startswith('no space left on the device' + (
        ' (writing /w/c/2' if isinstance(error, ValueError) else f' of {tmp_path}:'))
    assert 'no checkpoint was written yet; free some space and rerun' in str(got.value)
    assert ('writing /w/c/2.orbax-checkpoint-tmp/d/ab' in str(got.value)) == (
        isinstance(error, ValueError))
  else:
    assert got.value is error


def test_training_reports_a_full_disk_on_one_line(tmp_path, monkeypatch):
  from ld_mpc_jax.runs import train
  monkeypatch.setattr(sys, 'unraisablehook', sys.unraisablehook)  # As they were, after it.
  monkeypatch.setattr(threading, 'excepthook', threading.excepthook)
  def fills(plans, workdir):
    raise OSError(28, 'No space left on device', os.path.join(workdir, 'eval.csv'))
  monkeypatch.setattr(train, '_train_offline', fills)
  with pytest.raises(checkpointing.DiskFullError, match=r'\(writing eval.csv\): no checkpoint'):
    train.train_and_evaluate(door_open.get_config('smoke'), str(tmp_path))


def test_a_full_disk_names_every_seeds_checkpoint_and_a_file_elsewhere(tmp_path):
  for seed, steps in ((0, (40, 80)), (1, (40,))):  # Seed 1 stopped before its step 80.
    for step in steps:
      os.makedirs(tmp_path / f'seed{seed}' / 'checkpoints' / str(step))
  line = checkpointing.disk_full_message(str(tmp_path), '/data/x.npz')
  assert line == ('no space left on the device (writing /data/x.npz): checkpoint step 40 and '
                  f'those before it are kept in {tmp_path}/seed*/checkpoints; free some space '
                  'and rerun the same command to resume from it')
  assert checkpointing.disk_full_message(str(tmp_path / 'new'), None) == (
      f'no space left on the device of {tmp_path}/new: no checkpoint was written yet; free some '
      'space and rerun the same command')


def test_after_a_full_disk_its_exit_noise_is_dropped(tmp_path, monkeypatch):
  seen = []
  monkeypatch.setattr(sys, 'unraisablehook', lambda u: seen.append(u.exc_value))
  monkeypatch.setattr(threading, 'excepthook', lambda a: seen.append(a.exc_value))
  with pytest.raises(checkpointing.DiskFullError):
    with checkpointing.stop_when_disk_full(str(tmp_path)):
      raise OSError(28, 'No space left on device')
  unraisable = lambda error: type('U', (), dict(exc_type=type(error), exc_value=error,
                                                exc_traceback=None, object=None))()
  sys.unraisablehook(unraisable(OSError(28, 'No space left on device')))  # tensorboardX's
  thread = threading.Thread(target=lambda: (_ for _ in ()).throw(OSError('handle is closed')))
  thread.start()  # atexit flush, then its writer thread: dropped.
  thread.join()
  assert seen == []
  other = KeyError('x')
  sys.unraisablehook(unraisable(other))  # Anything else is still reported.
  thread = threading.Thread(target=lambda: (_ for _ in ()).throw(other))
  thread.start()
  thread.join()
  assert seen == [other, other]
