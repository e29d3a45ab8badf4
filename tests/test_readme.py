"""README.md's commands run as written: every `python -m experiments.X ...` it shows names a module
that exists and flags (and config fields, presets and the `--config.` fields of modes that load a saved run) that parse. Dry run only:
the flags are parsed in a subprocess per module, nothing is trained or evaluated."""

import collections
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys

import pytest

from ld_mpc_jax import cli

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Run in a subprocess per module (each module defines its flags on absl's global FLAGS): parses
# each argv of sys.argv[2] (a JSON list) as the module's own launcher would, and prints a JSON
# list with None or the error of each.
_CHECK = r'''
import importlib, json, sys
from absl import flags
from ld_mpc_jax import cli
from ld_mpc_jax.configs import door_open, resolve_config_arg
from ld_mpc_jax.configs.overrides import parse_items, with_overrides
name, commands = sys.argv[1], json.loads(sys.argv[2])
module = importlib.import_module(name)  # The mode's module, ld_mpc_jax.cli.<mode>.
if hasattr(module, 'define_flags'):
  module.define_flags()
FLAGS, errors = flags.FLAGS, []
for argv in commands:
  FLAGS.unparse_flags()
  for flag in [f for f in FLAGS if f.startswith('config.')]:  # Defined by the last parse.
    delattr(FLAGS, flag)
  try:
    argv, items = resolve_config_arg(argv), []  # As ld_mpc_jax.cli.dispatch does.
    if hasattr(module, 'OVERRIDES'):
      argv, items = cli.split_config_overrides(argv)
    sys.argv = [name] + argv  # ml_collections reads the --config.x overrides from sys.argv.
    FLAGS(sys.argv)  # Unknown flags or config fields, bad values, missing flags.
    if 'config' in FLAGS and FLAGS['config'].present:
      FLAGS.config.to_dict()  # The config file and its :preset load.
    if items:  # Every --config.field of a mode that loads a saved config exists and parses.
      with_overrides(door_open.get_config(), parse_items(items))
    errors.append(None)
  except Exception as err:  # pylint: disable=broad-except
    errors.append(f'{type(err).__name__}: {err}')
print(json.dumps(errors))
'''


def readme_commands(text: str):
  """Every `python -m experiments.X ...` of a README's shell code blocks and of the backticked
  spans of its prose, as argument lists ['experiments.X', '--flag=value', ...]; continued lines
  joined, `&&` chains split, comments dropped."""
  code, prose, fence = [], [], None
  for line in text.splitlines():
    if line.startswith('```'):
      fence = None if fence is not None else line[3:].strip()
    elif fence is None:
      prose.append(line)
    elif fence in ('', 'bash', 'sh', 'shell'):
      code.append(line)
  found = [part for line in '\n'.join(code).replace('\\\n', ' ').splitlines()
           for part in line.split('&&')]
  found += re.findall(r'`([^`]+)`', '\n'.join(prose))
  return [shlex.split(c, comments=True)[2:] for c in map(str.strip, found)
          if c.startswith('python -m experiments.')]


def check_commands(commands, cwd):
  """{tuple(command): None or the error} for argument lists as `readme_commands` gives them."""
  by_module, results = collections.defaultdict(list), {}
  for command in commands:
    if importlib.util.find_spec(command[0]) is None:
      results[tuple(command)] = f'no module {command[0]}'
      continue
    cmd = importlib.import_module(command[0])
    try:
      mode, argv = cli.choose(command, cmd.MODES, cmd.DEFAULT, cmd.BY_FLAG)
    except ValueError as err:
      results[tuple(command)] = str(err)
      continue
    by_module[f'ld_mpc_jax.cli.{mode}'].append((command, argv[1:]))
  procs = {}
  for module, group in by_module.items():
    procs[module] = subprocess.Popen(
        [sys.executable, '-c', _CHECK, module, json.dumps([argv for _, argv in group])], cwd=cwd,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONPATH=REPO))
  for module, proc in procs.items():  # Started together: the imports overlap.
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err[-2000:]
    results.update(zip((tuple(c) for c, _ in by_module[module]),
                       json.loads(out.splitlines()[-1])))
  return results


@pytest.fixture(scope='module')
def readme():
  with open(os.path.join(REPO, 'README.md')) as f:
    return f.read()


def test_the_readme_commands_parse(readme, tmp_path):
  commands = readme_commands(readme)
  modules = {c[0] for c in commands}
  assert {'experiments.train', 'experiments.evaluate'} <= modules, modules  # Parsing found them.
  bad = {' '.join(c): e for c, e in check_commands(commands, tmp_path).items() if e}
  assert not bad, bad
  assert not os.listdir(tmp_path)  # A dry run: nothing written.


def test_the_readme_shows_every_command_and_experiments_holds_only_the_seven(readme):
  shown = {c[0].split('.', 1)[1] for c in readme_commands(readme)}
  commands = {f[:-3] for f in os.listdir(os.path.join(REPO, 'experiments'))
              if f.endswith('.py') and f != '__init__.py'}
  assert commands == {'train', 'evaluate', 'collect', 'report', 'diagnose', 'benchmark_planning',
                      'benchmark_training'}
  assert shown == commands, shown ^ commands
  for name in commands:  # Thin: the code lives in ld_mpc_jax.cli.
    with open(os.path.join(REPO, 'experiments', f'{name}.py')) as f:
      assert f.read().count('\n') <= 120, name
    for mode in importlib.import_module(f'experiments.{name}').MODES.values():
      assert importlib.util.find_spec(f'ld_mpc_jax.cli.{mode}') is not None, (name, mode)


def test_a_command_that_does_not_exist_is_caught(tmp_path):
  text = '''```bash
python -m experiments.train --config=door_open.py:cpu --workdir=DIR \\
  --config.train.num_seeds=3   # a comment
python -m experiments.train --config=door_open.py:cpu --workdir=DIR --no_such_flag=1
```
| `python -m experiments.train --config=door_open.py:nopreset --workdir=DIR` | x |
| `python -m experiments.train --config=door_open.py --workdir=DIR --config.plan.nope=1` | x |
| `python -m experiments.evaluate --workdir=DIR --config.plan.safe_selection=True,plan.safe_margin=2`
| `python -m experiments.evaluate --seeds=0` | x |
| `python -m experiments.nope --workdir=DIR` | x |
| `python -m experiments.evaluate --workdir=DIR --set=plan.safe_selection=True` | x |
| `python -m experiments.report nomode a.json` | x |
| `python -m experiments.evaluate selection --workdir=A --workdir=B --out=x.json --config.plan.nope=1`
| `python -m experiments.train --config=door_open.py:cpu --seeds=0,1 --workdir=DIR --config.seed=2`
| `python -m experiments.train --config=door_open.py:cpu --workdir=DIR --config.train.num_seeds=2`
'''
  commands = readme_commands(text)
  assert commands[0] == ['experiments.train', '--config=door_open.py:cpu', '--workdir=DIR',
                         '--config.train.num_seeds=3']
  found = check_commands(commands, tmp_path)  # One subprocess per module for all of them.
  errors = [found[tuple(c)] for c in commands]
  assert errors[0] is None, errors[0]
  assert 'no_such_flag' in errors[1]
  assert 'nopreset' in errors[2]
  assert 'nope' in errors[3]
  assert "'plan.safe_selection'" in errors[4]  # One field per flag: 'True,plan...' is no bool.
  assert 'workdir' in errors[5]  # A required flag left out.
  assert errors[6] == 'no module experiments.nope'
  assert '--config.field=value' in errors[7]  # The old spelling, named.
  assert 'unknown mode' in errors[8] and 'curves' in errors[8]
  assert errors[9] is not None  # selection: fields are checked only where the mode loads a
  assert errors[10] is None     # config; the sweep mode (--seeds) takes --config.x itself.
  assert errors[11] is None  # A field the first command set too: each command parses afresh.


def test_the_plan_snippet_runs_as_written_and_prints_what_it_computes(readme, tmp_path):
  """Issue 104: the README's `plan()` snippet printed nothing when run as a file."""
  snippet = re.search(r'```python\n(.*?)```', readme, re.S).group(1)
  (tmp_path / 'snippet.py').write_text(snippet)
  done = subprocess.run([sys.executable, 'snippet.py'], cwd=tmp_path, capture_output=True,
                        text=True, timeout=300, env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 0, done.stderr[-3000:]
  action, shape, kind = done.stdout.strip().splitlines()[-3:]
  assert len(action.strip('[]').split()) == 4  # The first action [4].
  assert re.fullmatch(r'\(\d+,\)', shape)
  assert kind.split()[0] in ('proposal', 'actor_prior', 'gaussian', 'refined')
