"""Pools evaluation JSONs (experiments.evaluate --out) from per-episode records.

  python -m experiments.report runs/a/evaluation.json runs/b/evaluation.json ...
  python -m experiments.report runs/online/ft_seed{0,1,2}/episodes.csv
  python -m experiments.report run/seed0/episodes.csv.gz+bc/seed0.json.gz ...  # with BC
  python -m experiments.report runs/seed0_first.json+runs/seed0_more.json runs/seed1.json
  python -m experiments.report --noise_plot=noise.png runs/s{0,1,2}/evaluation.json  # sweeps
  python -m experiments.report --check=results/readme_rows.json  # README numbers vs records

A file is an `experiments.evaluate --out` JSON, an `experiments.evaluate selection --out` JSON or
a run's own `episodes.csv` (training or online fine-tuning). Each file's records count once. A
file is one `run`, named by its path; a file whose records name several runs (compare_selection
over several workdirs) keeps them apart as PATH:RUN, so episodes of different checkpoints never
pair up. Prints per goal split and policy the pooled successes with a Wilson
interval and the rate of each file, then exact McNemar tests between policies on the same
episodes. Multi-task evaluations (records with a `task`) first get the per-task table of
`multitask_eval`, pooled over the files; single-task files given with them (to pool several
settings into one test) join the pooled table, not the per-task one.

PATH#TAG renames the file's policies POLICY#TAG: `seed0.json+filter_seed0.json#f` pairs the planner
with itself evaluated under other settings (plan vs plan#f) on the same episodes.

A+B (paths joined by '+') is one file made of both: evaluations of the same checkpoints by two
commands (a policy added later on the same episodes), so that their policies pair. A policy's
episode in both (the deterministic actor prior, say) counts once, and must have the same outcome
in both.
"""

import gzip
import json
import os
import re
import sys

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.eval import evaluation_suite, multitask_eval, run_files


def named_records(results: list, names: list) -> list:
  """The records of [evaluate JSON dicts], each file's `run` renamed by its name (NAME:RUN where
  a file holds several runs), so that episodes of different files or checkpoints never pair.
  Records without a `run` (an evaluation of one checkpoint) belong to the file's one run."""
  records = []
  for result, name in zip(results, names):
    several = len({str(r['run']) for r in result['records'] if r.get('run') is not None}) > 1
    for r in result['records']:
      records.append({**r, 'run': f"{name}:{r.get('run')}" if several else name})
  return records


def pool(results: list, names: list) -> dict:
  """[evaluate JSON dicts], [their names] -> evaluation_suite.summarize of all their records."""
  return evaluation_suite.summarize(named_records(results, names))


def read_json(path: str) -> dict:
  """The JSON file at `path` (gzip-compressed if it ends in .gz); a file that cannot be read ends
  the program with one line, code 2."""
  try:
    with (gzip.open(path, 'rt') if path.endswith('.gz') else open(path)) as f:
      return json.load(f)
  except (OSError, EOFError, json.JSONDecodeError) as err:
    cli.fail(f'cannot read {path}: {err}')


def _tagged(path: str):
  """(the file's path, its tag): PATH#TAG names every policy of the file POLICY#TAG, so that two
  evaluations of the same checkpoints with other settings pair as different policies."""
  path, _, tag = path.partition('#')
  return path, tag


def _tag(records: list, tag: str) -> list:
  return [dict(r, policy=f"{r['policy']}#{tag}") for r in records] if tag else records


def read_records(path: str) -> list:
  """The per-episode records of an evaluation JSON or of a run's episodes.csv (either may be
  gzip-compressed, .gz); PATH#TAG tags its policies (`_tagged`)."""
  path, tag = _tagged(path)
  return _tag(_read_records(path), tag)


def _read_records(path: str) -> list:
  if not path.endswith(('.csv', '.csv.gz')):
    result = read_json(path)
    records = result.get('records')
    outcomes = result.get('outcomes')
    if records is None and outcomes and isinstance(outcomes[0], dict):
      # `evaluate bc` without --run used to write its episodes as `outcomes` only
      # (results/noise/offline_door_medium_mask_859bac5/bc.json.gz).
      records = [dict(o, policy='bc') for o in outcomes]
    if records is None:
      cli.fail(f'{path} has no per-episode records (written by an older evaluate?)')
    return records
  if not os.path.exists(path):
    cli.fail(f'cannot read {path}: no such file')
  return run_files.read_records(path)


def _key(r: dict) -> tuple:
  return tuple(str(r.get(k)) for k in ('run', 'task', 'policy', 'split', 'eval_seed', 'episode'))


def read_joined(arg: str, reader=None) -> list:
  """The records of one path, or of paths joined by '+' as one file: an episode of a policy in
  several keeps the first, and differing outcomes end the program with one line. Records without
  a `run` take the join's run where the others name exactly one. `reader`: path -> records
  (default `read_records`)."""
  reader = reader or read_records
  if '+' not in arg:
    return reader(arg)
  parts = [reader(path) for path in arg.split('+')]
  runs = {r['run'] for part in parts for r in part if r.get('run') is not None}
  if len(runs) == 1:  # Run-less records (one checkpoint's evaluation JSON) are the join's one run.
    (run,) = runs
    parts = [[r if r.get('run') is not None else dict(r, run=run) for r in part] for part in parts]
  records, seen = [], {}
  for part in parts:
    for r in part:
      k = _key(r)
      if k in seen:
        if int(seen[k]['success']) != int(r['success']):
          cli.fail(f'{arg}: episode {r.get("episode")} of {r.get("policy")} is a success in '
                   f'one file and not in another; these are not the same checkpoints')
        continue
      seen[k] = r
      records.append(r)
  return records


def _noise_records(result: dict) -> list:
  """A file's noise-sweep records; a sweep without std 0 gets the file's protocol records as
  std 0 (the same held-out episodes without noise), as bc_baseline --noise_stds writes it."""
  sweep = result.get('noise_sweep', {}).get('records', [])
  if sweep and not any(float(r['obs_noise']) == 0 for r in sweep):
    sweep = [dict(r, obs_noise=0.0) for r in result.get('records') or []
             if r.get('split', 'held_out') == 'held_out'] + sweep
  return sweep


def _cell_records(arg: str, obs_noise) -> list:
  """The records a manifest number reads from one of its files (`read_joined`): the protocol
  records (None), or the noise sweep's at that std (every '+' part a sweep JSON;
  `_noise_records`), as ordinary records, so that they count and pair like them."""
  def sweep_at(path: str) -> list:
    path, tag = _tagged(path)
    if path.endswith(('.csv', '.csv.gz')):
      cli.fail(f'{path}: a noise cell reads a noise sweep (evaluate --noise_sweep --out), not '
               'episodes.csv')
    return _tag([r for r in _noise_records(read_json(path))
                 if abs(float(r['obs_noise']) - float(obs_noise)) < 1e-9], tag)
  return read_joined(arg, None if obs_noise is None else sweep_at)


def check(manifest_path: str, readme_path: str = 'README.md') -> list:
  """The README numbers of the manifest that disagree with their records (empty: all agree).
  Paths in the manifest are relative to its repository (the manifest's folder's parent). A
  number with `obs_noise` reads the files' observation-noise sweeps at that std."""
  root = os.path.dirname(os.path.dirname(os.path.abspath(manifest_path)))
  manifest = read_json(manifest_path)
  if not os.path.isfile(os.path.join(root, readme_path)):
    raise ValueError(f'--check={manifest_path}: no {readme_path} in {root}, the folder above the '
                     "manifest's (a manifest lives in its repository's results/)")
  with open(os.path.join(root, readme_path)) as f:
    readme = f.read().splitlines()
  failures = []
  for row in manifest['rows']:
    lines = [l for l in readme if row['line'] in l]
    if len(lines) != 1:
      failures.append(f"{row['line']!r}: {len(lines)} README lines show it, not 1")
      continue
    shown = readme_shows(lines[0], [num['expect'] for num in row['numbers']])
    for num, in_readme in zip(row['numbers'], shown):
      files = ['+'.join(os.path.join(root, p) for p in f.split('+')) for f in num['files']]
      noise = num.get('obs_noise')
      got = (_paired_cell(files, *num['pair'], obs_noise=noise) if 'pair' in num
             else _count_cell(files, num['policy'], obs_noise=noise))
      if got != num['expect'] or in_readme != num['expect']:
        what = ' vs '.join(num['pair']) if 'pair' in num else num['policy']
        what += '' if noise is None else f' at obs noise {noise}'
        manifest_says = '' if in_readme == num['expect'] else f", manifest {num['expect']}"
        failures.append(f"{row['line']!r}, {what}: README {in_readme}{manifest_says}, "
                        f'records {got}')
  return failures


# A count ('145/150') or a paired test ('34 / 0, 1.2e-10') as the README writes them.
_NUMBER = re.compile(r'\d+ / \d+, \d+(?:\.\d+)?(?:e-?\d+)?|\d+/\d+')


def readme_shows(line: str, expected: list) -> list:
  """What a README line shows in the place of each manifest number, in the manifest's order.

  A table row: its cells after the first that start with a count or a paired test, left to
  right, one per number (so swapped cells disagree; missing ones show as 'nothing'). A line of
  prose: each number must appear after the one before it (the same position again for a
  repeated number), bounded by non-digits; one that does not shows as 'not in order'.
  """
  if line.lstrip().startswith('|'):
    cells = [c.strip() for c in line.strip().strip('|').split('|')][1:]
    tokens = [m.group(0) for m in (_NUMBER.match(c) for c in cells) if m]
    return [tokens[i] if i < len(tokens) else 'nothing' for i in range(len(expected))]
  out, start, start_after, previous = [], 0, 0, None
  for want in expected:
    at = start if want == previous else start_after
    found = None
    for m in _NUMBER.finditer(line, at):
      if m.group(0) == want:
        found = m
        break
    if found is None:
      out.append('not in order')
      continue
    out.append(want)
    start, start_after, previous = found.start(), found.end(), want
  return out


def _count_cell(files: list, policy: str, obs_noise=None) -> str:
  """'successes/episodes' of `policy` on held-out goals over `files` (at `obs_noise`: its sweep)."""
  mine = [r for f in files for r in _cell_records(f, obs_noise)
          if r['policy'] == policy and r.get('split', 'held_out') == 'held_out']
  return f"{sum(int(r['success']) for r in mine)}/{len(mine)}"


def _paired_cell(files: list, a: str, b: str, obs_noise=None) -> str:
  """'A-only / B-only, p' of the exact McNemar test of policies a and b over `files` (each file's
  episodes pair only within it), p to two significant digits (1.4e-9 for small ones)."""
  paired = pool([{'records': _cell_records(f, obs_noise)} for f in files], files)['held_out']['paired']
  if f'{a} vs {b}' in paired:
    t = paired[f'{a} vs {b}']
    a_only, b_only = t['a_only'], t['b_only']
  elif f'{b} vs {a}' in paired:
    t = paired[f'{b} vs {a}']
    a_only, b_only = t['b_only'], t['a_only']
  else:
    return f'no paired episodes of {a} and {b}'
  p = t['p_value']
  mantissa, exponent = f'{p:.1e}'.split('e')
  text = f'{p:.2g}' if p >= 1e-4 else f'{mantissa}e{int(exponent)}'
  return f'{a_only} / {b_only}, {text}'


def define_flags() -> None:
  """The mode's flags (defined on use only: tests import this module beside other flags)."""
  from absl import flags  # pylint: disable=g-import-not-at-top
  flags.DEFINE_multi_string('check', [], 'A manifest of README numbers (results/readme_rows.json): '
                            'recompute each from its records; exit code 1 on any difference.')
  flags.DEFINE_string('noise_plot', None, 'PNG of the pooled observation-noise sweep.')


def main(argv: list) -> None:
  from absl import flags  # pylint: disable=g-import-not-at-top
  paths, manifests, plot_path = list(argv[1:]), flags.FLAGS.check, flags.FLAGS.noise_plot
  if manifests:
    with cli.one_line_errors():
      failures = [f for m in manifests for f in check(m)]
    print('\n'.join(failures) or f'every README number in {", ".join(manifests)} matches its records')
    sys.exit(1 if failures else 0)
  run(paths, plot_path)


def run(paths: list, plot_path: str | None = None) -> None:
  """Prints the pooled tables of record files `paths` (and the noise sweep's plot)."""
  if not paths:
    cli.fail('give one or more evaluation JSONs: python -m experiments.report A.json ...')
  results = [{'records': read_joined(path)} for path in paths]
  records = [r for res in results for r in res['records']]
  multi = [r for r in records if r.get('task') is not None]
  if multi:
    tasks = list(dict.fromkeys(r['task'] for r in multi))
    print(multitask_eval.markdown(multitask_eval.per_task(multi, tasks), tasks))
    if len(multi) < len(records):  # Single-task files as well: pooled with them below only.
      print(f'The per-task table has the multi-task files\' records only; the pooled table '
            f'below has all {len(records)} records.\n')
  print(evaluation_suite.markdown(pool(results, paths)), end='')
  parts = [(name, *_tagged(part)) for name in paths for part in name.split('+')]
  noisy = [{**r, 'run': name} for name, part, tag in parts if not part.endswith(('.csv', '.csv.gz'))
           for r in _tag(_noise_records(read_json(part)), tag)]
  if noisy:
    from ld_mpc_jax.analysis import noise_sweep  # pylint: disable=g-import-not-at-top
    rows = noise_sweep.table(noisy)
    print('\nObservation-noise sweep, pooled (held-out goals):\n\n' + noise_sweep.markdown(rows),
          end='')
    if plot_path:
      print(f'wrote {noise_sweep.plot(rows, plot_path)}')
  elif plot_path:
    cli.fail('--noise_plot: none of the files has a noise sweep (experiments.evaluate '
             '--noise_sweep)')
