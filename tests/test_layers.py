"""The package's import graph: no cycle, every import points down the layers (function-level
imports included); module and function sizes."""

import ast
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = 'ld_mpc_jax'


def _module_name(path: str, root: str) -> str:
  rel = os.path.relpath(path, root)[:-len('.py')].split(os.sep)
  return '.'.join(rel[:-1] if rel[-1] == '__init__' else rel)


def _imports(path: str, name: str, modules) -> set:
  """Modules of the package that `path` (module `name`) imports anywhere in its body."""
  is_pkg = path.endswith('__init__.py')
  base = name.split('.') if is_pkg else name.split('.')[:-1]
  out = set()
  for node in ast.walk(ast.parse(open(path).read())):
    targets = []
    if isinstance(node, ast.Import):
      targets = [a.name for a in node.names]
    elif isinstance(node, ast.ImportFrom):
      mod = node.module or ''
      if node.level:
        mod = '.'.join(base[:len(base) - node.level + 1] + ([mod] if mod else []))
      targets = [f'{mod}.{a.name}' for a in node.names]  # a.b.fn -> a.b below.
    for t in targets:
      while t and t not in modules:
        t = t.rpartition('.')[0]
      if t and t != name and t.startswith(PACKAGE):
        out.add(t)
  return out


def import_graph(root: str = ROOT) -> dict:
  """module -> set of package modules it imports, for every module under ld_mpc_jax."""
  paths = {}
  for d, _, files in os.walk(os.path.join(root, PACKAGE)):
    for f in files:
      if f.endswith('.py'):
        paths[_module_name(os.path.join(d, f), root)] = os.path.join(d, f)
  return {m: _imports(p, m, paths) for m, p in paths.items()}


def find_cycle(graph: dict):
  """One cycle as a list of modules [a, b, ..., a], or None. A package's __init__ importing its
  own submodules is not a cycle of the submodules; edges to a package from inside it are."""
  state, stack = {}, []

  def visit(m):
    state[m] = 1
    stack.append(m)
    for n in sorted(graph.get(m, ())):
      if m.startswith(n + '.'):  # A submodule importing its parent package's __init__.
        continue
      if state.get(n) == 1:
        return stack[stack.index(n):] + [n]
      if not state.get(n):
        found = visit(n)
        if found:
          return found
    stack.pop()
    state[m] = 2
    return None

  for m in sorted(graph):
    if not state.get(m):
      found = visit(m)
      if found:
        return found
  return None


def test_find_cycle_finds_a_planted_cycle():
  assert find_cycle({'a': {'b'}, 'b': {'c'}, 'c': {'a'}}) == ['a', 'b', 'c', 'a']
  assert find_cycle({'a': {'b'}, 'b': {'c'}, 'c': set()}) is None


def test_import_graph_sees_function_level_imports(tmp_path):
  pkg = tmp_path / PACKAGE
  pkg.mkdir()
  (pkg / '__init__.py').write_text('')
  (pkg / 'a.py').write_text('def f():\n  from ld_mpc_jax import b\n')
  (pkg / 'b.py').write_text('from ld_mpc_jax.a import f\n')
  graph = import_graph(str(tmp_path))
  assert graph[f'{PACKAGE}.a'] == {f'{PACKAGE}.b'}
  assert find_cycle(graph) is not None


def test_no_import_cycle():
  cycle = find_cycle(import_graph())
  if cycle:
    pytest.fail('import cycle: ' + ' -> '.join(cycle))


def test_modules_at_most_400_lines_and_functions_at_most_60():
  too_long = []
  for d, _, files in os.walk(os.path.join(ROOT, PACKAGE)):
    for f in files:
      if not f.endswith('.py'):
        continue
      path = os.path.join(d, f)
      rel = os.path.relpath(path, ROOT)
      source = open(path).read()
      is_config = rel.startswith(os.path.join(PACKAGE, 'configs'))  # Declarations.
      if source.count('\n') > 400:
        too_long.append(f'{rel}: {source.count(chr(10))} lines')
      for node in ast.walk(ast.parse(source)):
        if (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not is_config
            and node.end_lineno - node.lineno >= 60):
          too_long.append(f'{rel}:{node.name}: {node.end_lineno - node.lineno + 1} lines')
  assert not too_long, too_long


# The package's layers, lowest first, one folder each: a module imports only modules of its own
# folder or of folders below (BUILD.md, Layout). The root holds only __init__.py.
LAYERS = ('ops', 'configs', 'nets', 'envs', 'data', 'model', 'learn', 'plan', 'eval', 'online', 'runs',
          'analysis', 'cli')


def _layer_of(graph) -> dict:
  """module -> (layer index, folder); the package's own __init__ is above every folder."""
  out = {}
  for m in graph:
    parts = m.split('.')
    folder = parts[1] if len(parts) > 1 else ''
    out[m] = (LAYERS.index(folder) if folder in LAYERS else len(LAYERS), folder)
  return out


def test_the_root_holds_only_the_layer_folders():
  root = os.path.join(ROOT, PACKAGE)
  entries = {e for e in os.listdir(root) if not e.startswith(('__pycache__', '.'))}
  assert entries == {'__init__.py', *LAYERS}, sorted(entries - {'__init__.py', *LAYERS})
  for folder in LAYERS:
    assert os.path.isfile(os.path.join(root, folder, '__init__.py')), folder


def test_every_import_points_down_the_layers():
  graph = import_graph()
  layer = _layer_of(graph)
  upward = [f'{m} ({layer[m][1]}) imports {n} ({layer[n][1]})'
            for m, deps in graph.items() for n in deps
            if not m.startswith(n + '.') and layer[n][0] > layer[m][0]]
  assert not upward, upward


def test_the_layer_check_sees_an_upward_import(monkeypatch):
  graph = import_graph()
  graph[f'{PACKAGE}.ops.numerics'] = {f'{PACKAGE}.plan.planner'}
  monkeypatch.setattr(sys.modules[__name__], 'import_graph', lambda: graph)
  with pytest.raises(AssertionError,
                     match='ops.numerics \\(ops\\) imports ld_mpc_jax.plan.planner \\(plan\\)'):
    test_every_import_points_down_the_layers()


# Functions that take a whole ConfigDict (issue 103: typed settings at the boundaries instead).
# A ratchet: lower it as settings replace the config; the target is at most 30. (The migration's
# steps, ops/legacy.py, are not among them: they work on the saved config.json as plain dicts.)
MAX_CONFIG_TAKERS = 28


def config_takers(root: str = ROOT) -> list:
  """'module:function' for every function of the package with a parameter annotated ConfigDict
  (or named Settings), or unannotated and named config, cfg, base_config or run_config."""
  out = []
  for d, _, files in os.walk(os.path.join(root, PACKAGE)):
    for f in sorted(files):
      if not f.endswith('.py'):
        continue
      path = os.path.join(d, f)
      for node in ast.walk(ast.parse(open(path).read())):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
          continue
        args = node.args.posonlyargs + node.args.args + node.args.kwonlyargs
        if any(_takes_config(a) for a in args):
          out.append(f'{_module_name(path, root)}:{node.name}')
  return out


def _takes_config(arg: ast.arg) -> bool:
  if arg.annotation is not None:
    annotation = ast.unparse(arg.annotation)
    return 'ConfigDict' in annotation or annotation == 'Settings'
  return arg.arg in ('config', 'cfg', 'base_config', 'run_config')


def test_fewer_functions_take_the_whole_config():
  takers = config_takers()
  assert len(takers) <= MAX_CONFIG_TAKERS, (len(takers), takers)


def test_only_the_configs_clone_a_config():
  """Variants of a config are made by configs.overrides.with_overrides (or are settings
  replaced: dataclasses.replace), not by cloning it elsewhere."""
  clones = []
  for d, _, files in os.walk(os.path.join(ROOT, PACKAGE)):
    for f in files:
      path = os.path.join(d, f)
      if f.endswith('.py') and os.sep + 'configs' + os.sep not in path:
        if 'ConfigDict(' in open(path).read() and '.to_dict())' in open(path).read():
          clones.extend(f'{path}:{i + 1}' for i, line in enumerate(open(path))
                        if 'ConfigDict(' in line and '.to_dict())' in line)
  assert not clones, clones
