"""experiments.train: a workdir of another config, in use, or with a damaged config.json ends in
one line and exit code 2 (the table of other mistakes: test_cli_probes.py)."""

import os
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_a_workdir_of_another_config_is_one_line_and_exit_code_2(tmp_path):
  from ld_mpc_jax.configs import door_open
  from ld_mpc_jax.learn import checkpointing
  workdir = tmp_path / 'run'
  checkpointing.save_config(door_open.get_config('smoke'), str(workdir))
  done = subprocess.run([sys.executable, '-m', 'experiments.train', f'--workdir={workdir}',
                         '--config=door_open.py:smoke', '--config.seed=5'],
                        cwd=tmp_path, capture_output=True, text=True, timeout=120,
                        env=dict(os.environ, PYTHONPATH=REPO))
  lines = [l for l in done.stderr.splitlines() if l.startswith('error: ')]
  assert done.returncode == 2, done.stderr[-3000:]
  assert len(lines) == 1 and 'seed (0 -> 5)' in lines[0], done.stderr[-3000:]
  assert 'Traceback' not in done.stderr
  assert os.listdir(workdir) == [checkpointing.CONFIG_FILE]


def test_a_workdir_in_use_is_refused_at_once_naming_its_pid(tmp_path):
  """Issue 102: a second run on a workdir whose lock another process holds exits 2 on one line
  naming the holder's pid, and writes nothing; the lock goes when its holder's block ends."""
  from ld_mpc_jax.runs import lock
  workdir = tmp_path / 'run'
  with lock.workdir_lock(str(workdir)):
    assert (workdir / lock.LOCK_FILE).read_text().strip() == str(os.getpid())
    with pytest.raises(lock.WorkdirBusyError, match=f'pid {os.getpid()}'):
      with lock.workdir_lock(str(workdir)):
        pass  # A second open file description: refused as another process would be.
    done = subprocess.run([sys.executable, '-m', 'experiments.train', f'--workdir={workdir}',
                           '--config=door_open.py:smoke'], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env=dict(os.environ, PYTHONPATH=REPO))
    lines = [l for l in done.stderr.splitlines() if l.startswith('error: ')]
    assert done.returncode == 2, done.stderr[-3000:]
    assert len(lines) == 1 and f'pid {os.getpid()}' in lines[0], done.stderr[-3000:]
    assert 'Traceback' not in done.stderr
    assert os.listdir(workdir) == [lock.LOCK_FILE]  # Nothing of a run was written.
  assert not workdir.exists()  # Created by the lock alone, so removed with it.


def test_a_stale_lock_file_is_taken_over(tmp_path):
  """A lock file whose holder died (SIGKILL leaves the file, the kernel drops the lock) does not
  block the next run."""
  from ld_mpc_jax.runs import lock
  workdir = tmp_path / 'run'
  workdir.mkdir()
  (workdir / lock.LOCK_FILE).write_text('999999\n')
  with lock.workdir_lock(str(workdir)):
    assert (workdir / lock.LOCK_FILE).read_text().strip() == str(os.getpid())
  assert workdir.exists() and not (workdir / lock.LOCK_FILE).exists()


@pytest.mark.parametrize('content', [b'\x83\x00binary', b'{"model": {"width": ', b'[1, 2]'])
def test_a_damaged_config_json_is_one_line_naming_it(tmp_path, content):
  """Issue 102: a damaged config.json gave a 30-line UnicodeDecodeError or a 38-line
  JSONDecodeError; now one line naming the file, from resume and from evaluate alike."""
  from ld_mpc_jax.learn import checkpointing
  workdir = tmp_path / 'run'
  workdir.mkdir()
  (workdir / checkpointing.CONFIG_FILE).write_bytes(content)
  with pytest.raises(checkpointing.WorkdirError, match='config.json is damaged'):
    checkpointing.load_config(str(workdir))
  if content != b'\x83\x00binary':  # One launcher run (the unit check covers the rest).
    return
  done = subprocess.run([sys.executable, '-m', 'experiments.evaluate', f'--workdir={workdir}',
                         f'--out={tmp_path / "e.json"}'], cwd=tmp_path, capture_output=True,
                        text=True, timeout=120, env=dict(os.environ, PYTHONPATH=REPO))
  lines = [l for l in done.stderr.splitlines() if l.startswith('error: ')]
  assert done.returncode == 2 and 'Traceback' not in done.stderr, done.stderr[-3000:]
  assert len(lines) == 1 and 'config.json is damaged' in lines[0]


def test_a_hand_edited_config_is_blamed_not_the_checkpoints(tmp_path):
  """A valid JSON config with an invalid setting: the line names config.json and the setting,
  and does not advise moving the (intact) checkpoints aside."""
  from ld_mpc_jax.configs import door_open
  from ld_mpc_jax.learn import checkpointing
  config = door_open.get_config('smoke')
  config.model.width = -3
  checkpointing.save_config(config, str(tmp_path))
  with pytest.raises(checkpointing.WorkdirError) as err:
    checkpointing.load_for_evaluation(str(tmp_path))
  assert 'config.json is not a valid config' in str(err.value)
  assert 'config.model.width' in str(err.value) and 'aside' not in str(err.value)
