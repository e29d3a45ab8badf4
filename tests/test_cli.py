"""Launchers: bad input gives one line on stderr and exit code 2, before any work starts."""

import os
import re
import subprocess
import sys

import pytest

from ld_mpc_jax.cli import errors as cli

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize('args,message', [
    (['experiments.collect', '--task=door-openn-v3', '--out=x.npz'], "'door-openn-v3'"),
    (['experiments.evaluate', 'bc', '--steps=0'], '--steps must be >= 1, got 0'),
    (['experiments.train', 'ablations', '--variants=ldmpc,nope'], "unknown variants ['nope']"),
    (['experiments.benchmark_planning', '--widths=huge'], "unknown widths ['huge']"),
    # Issue 102: each of these failed only after minutes of work.
    (['experiments.diagnose', '--workdir=w', '--episodes=0'], '--episodes must be >= 1, got 0'),
    (['experiments.evaluate', '--workdir=w', '--episodes=1000000000000'],
     '--episodes must be between 1 and 100,000'),
    (['experiments.benchmark_training', '--repeats=0'], '--repeats and --online_waves must be'),
    (['experiments.train', '--config=door_open.py:smoke', '--seeds=0,1',
      '--config.train.num_seeds=2'], 'drop --config.train.num_seeds=2'),
])
def test_bad_flag_is_one_line_and_exit_code_2(tmp_path, args, message):
  done = subprocess.run([sys.executable, '-m', *args], cwd=tmp_path, capture_output=True,
                        text=True, timeout=120, env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 2, done.stderr[-2000:]
  log = re.compile(r'^([IWEF]\d{4} |WARNING)')  # absl/library log lines are not the message.
  lines = [l for l in done.stderr.splitlines() if l.strip() and not log.match(l)]
  assert len(lines) == 1 and lines[0].startswith('error: ') and message in lines[0], lines
  assert not os.listdir(tmp_path)  # Nothing was written.


def test_one_line_errors_passes_other_exceptions_through():
  with pytest.raises(SystemExit) as exit_info:
    with cli.one_line_errors():
      raise FileNotFoundError('no checkpoint in runs/x')
  assert exit_info.value.code == 2
  with pytest.raises(KeyError):  # A bug, not bad input: its traceback is kept.
    with cli.one_line_errors():
      raise KeyError('params')


def test_an_existing_output_is_kept_unless_overwrite(tmp_path):
  path = tmp_path / 'evaluation.json'
  cli.check_new_output(str(path), overwrite=False)  # Free: no error.
  path.write_text('{"step": 4000}')
  with pytest.raises(ValueError, match='evaluation.json exists'):
    cli.check_new_output(str(path), overwrite=False)
  cli.check_new_output(str(path), overwrite=True)
  assert path.read_text() == '{"step": 4000}'  # The check itself never touches the file.


def test_config_args_in_either_form_come_back_joined_and_resolved():
  from ld_mpc_jax.configs import CONFIG_DIR, resolve_config_arg
  argv = ['prog', '--config', 'door_open.py:cpu', '--config.seed', '3', '--config.plan.pessimism',
          '-0.5', '--config.flag', '--workdir=w', '--config.data.preset=weak']
  assert resolve_config_arg(argv) == [
      'prog', f'--config={os.path.join(CONFIG_DIR, "door_open.py")}:cpu', '--config.seed=3',
      '--config.plan.pessimism=-0.5', '--config.flag', '--workdir=w', '--config.data.preset=weak']


def test_an_output_that_cannot_be_written_is_refused_before_the_work(tmp_path):
  blocker = tmp_path / 'a_file'
  blocker.write_text('x')
  with pytest.raises(ValueError, match=r'a_file/out/evaluation.json cannot be written \(.*a_file '
                                       r'is not a folder\); choose another --out'):
    cli.check_new_output(str(blocker / 'out' / 'evaluation.json'), overwrite=False)
  with pytest.raises(ValueError, match='is a folder'):
    cli.check_new_output(str(tmp_path), overwrite=True)
  cli.check_new_output(str(tmp_path / 'new' / 'deeper' / 'e.json'), overwrite=False)
  assert sorted(os.listdir(tmp_path)) == ['a_file']  # Checking made no folder and no file.


def test_collect_keeps_an_existing_dataset_unless_overwrite(tmp_path):
  """Issue 102: `collect --out=EXISTING` replaced the dataset silently; now it refuses on one
  line before collecting, and the file is untouched."""
  out = tmp_path / 'door.npz'
  out.write_bytes(b'an earlier dataset')
  done = subprocess.run([sys.executable, '-m', 'experiments.collect', f'--out={out}',
                         '--episodes=1'], cwd=tmp_path, capture_output=True, text=True,
                        timeout=120, env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 2, done.stderr[-2000:]
  lines = [l for l in done.stderr.splitlines() if l.startswith('error: ')]
  assert len(lines) == 1 and 'door.npz exists' in lines[0] and '--overwrite' in lines[0]
  assert out.read_bytes() == b'an earlier dataset'


@pytest.mark.parametrize('args,words', [
    (['experiments.train', '--config=door_opn.py:quick', '--workdir=w'],
     ['--config=door_opn.py:quick', 'no such config file', 'door_open.py']),
    (['experiments.train', '--config=door_open.py:quick', '--config.train.num_step=3',
      '--workdir=w'], ["'config.train.num_step'", "did you mean 'config.train.num_steps'?"]),
])
def test_a_mistyped_config_file_or_field_is_one_clean_line(tmp_path, args, words):
  """Issue 104: a mistyped config file gave a 36-line traceback (exit 1), a mistyped field a
  garbled repr of ml_collections' KeyError."""
  done = subprocess.run([sys.executable, '-m', *args], cwd=tmp_path, capture_output=True,
                        text=True, timeout=120, env=dict(os.environ, PYTHONPATH=REPO))
  lines = [l for l in done.stderr.splitlines() if l.startswith('error: ')]
  assert done.returncode == 2 and 'Traceback' not in done.stderr, done.stderr[-2000:]
  assert len(lines) == 1 and all(w in lines[0] for w in words), lines
  assert '\\' not in lines[0] and not os.listdir(tmp_path)


@pytest.mark.parametrize('command', ['train', 'evaluate', 'collect', 'report', 'diagnose',
                                     'benchmark_planning', 'benchmark_training'])
def test_help_exits_0(tmp_path, command):
  """Issue 104: every command's --help exited 1 (absl's default)."""
  done = subprocess.run([sys.executable, '-m', f'experiments.{command}', '--help'], cwd=tmp_path,
                        capture_output=True, text=True, timeout=120,
                        env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 0, done.stderr[-2000:]
  assert f'experiments.{command}' in done.stdout
