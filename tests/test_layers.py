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
      if source.count('\n') > 400:
        too_long.append(f'{rel}: {source.count(chr(10))} lines')
      for node in ast.walk(ast.parse(source)):
        if (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno >= 60):
          too_long.append(f'{rel}:{node.name}: {node.end_lineno - node.lineno + 1} lines')
  assert not too_long, too_long


# The package's layers, lowest first: a module imports only modules of its own layer or below
# (BUILD.md, Layout). A new module must be placed here.
LAYERS = (
    ('ops', ('config_cache', 'diffusion', 'ops', 'registry', 'stats', 'sharding', 'legacy')),
    ('nets', ('networks', 'networks.mlp', 'networks.transformer')),
    ('envs', ('envs', 'envs.suite', 'envs.goals', 'envs.metaworld_env')),
    ('model parts', ('actors', 'critics', 'proposals', 'dynamics', 'objective', 'search',
                     'tasks')),
    ('data', ('data', 'data.dataset', 'data.collection', 'data.replay', 'data.tdmpc2',
              'data.multitask', 'data.sources', 'data.demos', 'data.online_buffer')),
    ('config checks', ('config_checks', 'exploration')),
    ('model', ('models',)),
    ('learn', ('losses', 'train_state', 'checkpointing')),
    ('plan', ('planner', 'mppi', 'agent')),
    ('eval', ('evaluation', 'evaluation_suite', 'diagnostics', 'multitask_eval', 'run_files')),
    ('runs', ('runs', 'online_seats', 'online_report', 'online', 'train', '')),
)


def _layer_of() -> dict:
  return {(f'{PACKAGE}.{m}' if m else PACKAGE): (i, name)
          for i, (name, modules) in enumerate(LAYERS) for m in modules}


def test_every_import_points_down_the_layers():
  layer, graph = _layer_of(), import_graph()
  assert set(graph) == set(layer), ('modules not placed in LAYERS: '
                                    f'{sorted(set(graph) - set(layer))}')
  upward = [f'{m} ({layer[m][1]}) imports {n} ({layer[n][1]})'
            for m, deps in graph.items() for n in deps
            if not m.startswith(n + '.') and layer[n][0] > layer[m][0]]
  assert not upward, upward


def test_the_layer_check_sees_an_upward_import(monkeypatch):
  graph = import_graph()
  graph[f'{PACKAGE}.ops'] = {f'{PACKAGE}.planner'}
  monkeypatch.setattr(sys.modules[__name__], 'import_graph', lambda: graph)
  with pytest.raises(AssertionError, match='ops \\(ops\\) imports ld_mpc_jax.planner'):
    test_every_import_points_down_the_layers()
