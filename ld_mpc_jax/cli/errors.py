"""Launcher helpers: bad input gives one line on stderr and exit code 2, never a traceback."""

import ast
import contextlib
import os
import re
import sys
import tempfile
from typing import Iterable, NoReturn, Type


def fail(message) -> NoReturn:
  """Prints `error: message` on stderr and exits with code 2 (bad input)."""
  print(f'error: {message}', file=sys.stderr)
  sys.exit(2)


@contextlib.contextmanager
def one_line_errors(errors: Iterable[Type[BaseException]] = (ValueError, FileNotFoundError)):
  """Turns `errors` raised inside the block into `fail`. Wrap input checks, not long work."""
  try:
    yield
  except tuple(errors) as err:
    fail(err)


def check_subset(name: str, chosen: Iterable[str], valid: Iterable[str]) -> None:
  """ValueError naming the unknown entries of a list flag."""
  unknown = sorted(set(chosen) - set(valid))
  if unknown:
    raise ValueError(f'unknown {name} {unknown}; choose from {list(valid)}')


def check_new_output(path: str, overwrite: bool, flag: str = '--out') -> None:
  """ValueError when `path` exists and `overwrite` is off (an earlier result is never replaced
  silently), or when it cannot be written. Call it before the long work, so that a refusal costs
  nothing; it leaves no file behind."""
  if os.path.exists(path) and not overwrite:
    raise ValueError(f'{path} exists (an earlier result); choose another {flag} or pass '
                     '--overwrite')
  where = os.path.dirname(os.path.abspath(path))
  while not os.path.exists(where):  # The folder that will hold it (made later).
    where = os.path.dirname(where)
  try:
    if not os.path.isdir(where):
      raise NotADirectoryError(f'{where} is not a folder')
    if os.path.isdir(path):
      raise IsADirectoryError(f'{path} is a folder')
    with tempfile.TemporaryFile(dir=where):  # Writes there, as the result will.
      pass
  except OSError as err:
    raise ValueError(f'{path} cannot be written ({err}); choose another {flag}') from None


def check_workdir(path: str, flag: str = '--workdir') -> None:
  """ValueError when `path` cannot be a run directory: a file, or under one. Before any work."""
  if os.path.exists(path) and not os.path.isdir(path):
    raise ValueError(f'{flag}={path} is a file, not a run directory; choose another {flag}')
  where = os.path.dirname(os.path.abspath(path))
  while not os.path.exists(where):
    where = os.path.dirname(where)
  if not os.path.isdir(where):
    raise ValueError(f'{flag}={path} cannot be a run directory: {where} is a file')


def config_file_error(flag: str, spec: str, err: OSError) -> str:
  """One line for a config file that did not load (`flag`=`spec`): the file not found, with the
  shipped config files that take a :preset, or the error inside it."""
  from ld_mpc_jax.configs import CONFIG_DIR  # pylint: disable=g-import-not-at-top
  text = ' '.join(str(err).split())
  if isinstance(err, FileNotFoundError) or 'No such file or directory' in text:
    takes_preset = lambda n: 'def get_config(preset' in open(os.path.join(CONFIG_DIR, n)).read()
    shipped = sorted(n for n in os.listdir(CONFIG_DIR) if n.endswith('.py') and takes_preset(n))
    return (f'{flag}={spec}: no such config file; the shipped ones: {", ".join(shipped)} '
            '(or a path to your own)')
  return f'{flag}={spec}: {text}'


def int_list(flag: str, values: Iterable[str], least: int = 0) -> list:
  """The integers of a list flag, or ValueError naming the flag and the first bad entry."""
  out = []
  for v in values:
    try:
      out.append(int(v))
    except ValueError:
      raise ValueError(f'{flag}: {v!r} is not an integer') from None
    if out[-1] < least:
      raise ValueError(f'{flag}: {v} is below {least}')
  return out


def parse_flags(argv):
  """absl's flag parsing for `app.run(main, flags_parser=parse_flags)`, a bad flag failing in one
  line. A config file's own error (an unknown :preset) is reported without the traceback that
  ml_collections wraps into the flag error."""
  from absl import flags  # pylint: disable=g-import-not-at-top
  try:
    return flags.FLAGS(argv)
  except (AttributeError, KeyError) as err:  # ml_collections: an override of no such field.
    fail(_unknown_field(argv, err))
  except flags.Error as err:
    cause = err
    while cause.__cause__ or cause.__context__:
      cause = cause.__cause__ or cause.__context__
    name = re.match(r'flag (--[\w.-]+)', str(err))
    message = f'{name.group(1)}: {_plain(cause)}' if name and cause is not err else str(err)
    fail(' '.join(message.split()))  # One line.


def _plain(cause: BaseException) -> str:
  """A value error of a `--config.x=v` override in plain words, not Python's."""
  text = str(cause)
  found = re.match(r"invalid literal for int\(\) with base 10: ('.*')$", text)
  if found:
    return f'{found.group(1)} is not an integer'
  found = re.match(r"could not convert string to float: ('.*')$", text)
  if found:
    return f'{found.group(1)} is not a number'
  if 'Non-boolean argument to boolean flag' in text:
    value = re.search(r"'Non-boolean argument to boolean flag', ('.*?')\)", text)
    return f"{value.group(1) if value else 'the value'} is not True or False"
  return text


def _unknown_field(argv, err) -> str:
  """One line for a `--config.a.b=v` override that names a field the config does not have."""
  from ld_mpc_jax.ops.legacy import renamed_hint  # pylint: disable=g-import-not-at-top
  text = str(err.args[0]) if err.args else str(err)
  for _ in range(3):  # ml_collections nests reprs of the KeyError's message: unwrap them.
    try:
      inner = ast.literal_eval(text)
    except (ValueError, SyntaxError):
      break
    if not isinstance(inner, str):
      break
    text = inner
  first, _, rest = text.partition('\n')
  name = first.strip('"\'')
  suggestion = re.search(r'Did you mean "([\w.]+)"', rest)
  for arg in argv:
    flag = arg.split('=', 1)[0]
    parts = flag[2:].split('.')
    if flag.startswith('--') and name in parts[1:]:
      missing = '.'.join(parts[:parts.index(name, 1) + 1])
      near = '.'.join(parts[:parts.index(name, 1)] + [suggestion.group(1)]) if suggestion else ''
      hint = renamed_hint(missing) or (f' (did you mean {near!r}?)' if near else '')
      return f'{flag}: the config has no field {missing!r}{hint}'
  return f'a config override names a field the config does not have ({name!r})'
