"""Launchers: bad input gives one line on stderr and exit code 2, before any work starts."""

import os

import pytest

from ld_mpc_jax.cli import errors as cli


# The table of mistakes over the seven commands, and --help: test_cli_probes.py.


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
