"""The code of the seven commands in experiments/ (train, evaluate, collect, report, diagnose,
benchmark_planning, benchmark_training): each command is a table of modes, a mode one module here
with its flags and `main`.

Settings are overridden one way: `--config.field=value`. Commands that build their config from
flags (train) read them through ml_collections; modes that load a saved run's config declare
`OVERRIDES = []` and get the `field=value` items here, applied to the config they load.

`python -m experiments.evaluate mt10 --workdir=DIR` runs `ld_mpc_jax.cli.evaluate_mt10`; without a
mode word the command's default mode runs. A mode module's flags are defined when it is imported,
so only the chosen one's are (two modes may share a flag name).
"""

import importlib
import os
import sys
from typing import Dict, Optional, Sequence, Tuple

from ld_mpc_jax.cli import errors


def choose(argv: Sequence[str], modes: Dict[str, str], default: str,
           by_flag: Optional[Dict[str, str]] = None) -> Tuple[str, list]:
  """(module name, argv without the mode word) for a command line.

  A first argument that is not a flag names the mode; `by_flag` maps a flag (`--seeds`) that
  selects a mode by itself. An unknown mode word raises ValueError listing the modes; a first
  argument that looks like a path (a record file of `report`) goes to the default mode."""
  argv = list(argv)
  word = argv[1] if len(argv) > 1 and not argv[1].startswith('-') else None
  if word in modes:
    return modes[word], [f'{argv[0]} {word}'] + argv[2:]
  if word is not None and not _path_like(word):
    raise ValueError(f'unknown mode {word!r}; choose from {sorted(modes)} (or none: {default})')
  for flag, module in (by_flag or {}).items():
    if any(a == flag or a.startswith(flag + '=') for a in argv[1:]):
      return module, argv
  return default, argv


def _path_like(word: str) -> bool:
  return '/' in word or '.' in word or os.path.exists(word)


def split_config_overrides(argv: Sequence[str]) -> Tuple[list, list]:
  """(argv without its `--config.field=value` flags, ['field=value', ...]). A bare
  `--config.flag` is `flag=True`; `--set=...` (the old spelling) raises ValueError."""
  rest, items = [], []
  for arg in argv:
    if arg.startswith('--set=') or arg == '--set':
      raise ValueError(f'{arg}: settings are overridden with --config.field=value now '
                       '(e.g. --config.plan.safe_selection=True)')
    if arg.startswith('--config.'):
      name, sep, value = arg[len('--config.'):].partition('=')
      items.append(f'{name}={value if sep else True}')
    else:
      rest.append(arg)
  return rest, items


def _own_lines(mode_doc: str, command_doc: str) -> str:
  """The mode's docstring less the example lines the command's docstring already shows (--help
  printed them twice)."""
  shown = {l.strip() for l in command_doc.splitlines() if l.strip().startswith('python -m')}
  kept, dropped, previous = [], False, ''
  for line in (mode_doc or '').strip().splitlines():
    continued = dropped and previous.rstrip().endswith('\\')  # The rest of a dropped example.
    dropped = line.strip() in shown or continued
    if not dropped:
      kept.append(line)
    previous = line
  return '\n'.join(kept)


def dispatch(doc: str, modes: Dict[str, str], default: str,
             by_flag: Optional[Dict[str, str]] = None) -> None:
  """Runs the chosen mode's `main` under absl (bad flags: one line, exit code 2).

  `--help` prints the command's docstring (its modes) and the chosen mode's flags."""
  from absl import app, flags  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.configs import resolve_config_arg  # pylint: disable=g-import-not-at-top
  with errors.one_line_errors():
    name, argv = choose(sys.argv, modes, default, by_flag)
  module = importlib.import_module(f'ld_mpc_jax.cli.{name}')
  if hasattr(module, 'define_flags'):
    module.define_flags()
  argv = resolve_config_arg(argv)
  if hasattr(module, 'OVERRIDES'):  # The mode applies them to the config it loads.
    with errors.one_line_errors():
      argv, module.OVERRIDES = split_config_overrides(argv)
  sys.argv = argv
  main_module = sys.modules['__main__']
  main_module.__doc__ = f'{doc.strip()}\n\nThis mode ({name}): {_own_lines(module.__doc__, doc)}'
  for flag in flags.FLAGS.get_key_flags_for_module(module.__name__):
    flags.FLAGS.register_key_flag_for_module(sys.argv[0], flag)  # Shown by --help.
  asked_help = any(a in ('--help', '-h', '-?', '--helpshort', '--helpfull') for a in argv[1:])
  try:
    app.run(module.main, flags_parser=errors.parse_flags)
  except SystemExit as exit_:
    if asked_help and exit_.code == 1:  # absl exits 1 after printing the help asked for.
      sys.exit(0)
    raise
