"""Every README number with committed records recomputes from them (results/readme_rows.json),
and the check fails when a record or the README changes."""

import gzip
import json
import os
import shutil

from ld_mpc_jax.cli import pool as pool_evals

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = os.path.join(ROOT, 'results', 'readme_rows.json')


def test_readme_numbers_match_their_records():
  assert pool_evals.check(MANIFEST) == []


def _copy(tmp_path):
  """A copy of the README, the manifest and the files it names, under tmp_path."""
  manifest = json.load(open(MANIFEST))
  files = {p.partition('#')[0] for row in manifest['rows'] for n in row['numbers']
           for f in n['files'] for p in f.split('+')}  # PATH#TAG names the file PATH.
  for rel in files | {'README.md', 'results/readme_rows.json'}:
    os.makedirs(tmp_path / os.path.dirname(rel), exist_ok=True)
    shutil.copy(os.path.join(ROOT, rel), tmp_path / rel)
  return manifest


def test_the_check_fails_on_an_altered_record_or_readme(tmp_path):
  manifest = _copy(tmp_path)
  first = manifest['rows'][0]['numbers'][0]
  path = tmp_path / first['files'][0].split('+')[0]
  with gzip.open(path, 'rt') as f:
    lines = f.read().splitlines()
  header = lines[0].split(',')
  i = next(k for k, l in enumerate(lines[1:], 1)
           if l.split(',')[header.index('policy')] == first['policy']
           and l.split(',')[header.index('success')] == '1')
  cells = lines[i].split(',')
  cells[header.index('success')] = '0'  # One success of the counted policy undone.
  lines[i] = ','.join(cells)
  with gzip.open(path, 'wt') as f:
    f.write('\n'.join(lines) + '\n')
  failures = pool_evals.check(str(tmp_path / 'results' / 'readme_rows.json'))
  assert f"plan: README {first['expect']}" in failures[0]
  # The same episode moves the paired test too, when that row shows one.
  assert len(failures) == 1 + any('pair' in n for n in manifest['rows'][0]['numbers'])
  if len(failures) == 2:
    assert 'plan vs actor: README 1 / 2, 1' in failures[1]
  readme = (tmp_path / 'README.md').read_text()
  (tmp_path / 'README.md').write_text(readme.replace(manifest['rows'][1]['line'], 'gone'))
  assert len(pool_evals.check(str(tmp_path / 'results' / 'readme_rows.json'))) == len(failures) + 1


def test_the_check_recomputes_a_paired_test_from_the_records(tmp_path):
  manifest = _copy(tmp_path)
  row = next(r for r in manifest['rows'] if r['line'] == '| door-open `weak` |')
  num = next(n for n in row['numbers'] if 'pair' in n)
  assert pool_evals._paired_cell([os.path.join(ROOT, f) for f in num['files']], *num['pair']) == (
      '23 / 8, 0.011')
  assert pool_evals._paired_cell([os.path.join(ROOT, f) for f in num['files']],
                                 *reversed(num['pair'])) == '8 / 23, 0.011'  # Either order.


def test_a_noise_cell_reads_the_sweep_at_its_std(tmp_path):
  manifest = _copy(tmp_path)
  row = next(r for r in manifest['rows'] if any('obs_noise' in n for n in r['numbers']))
  num = next(n for n in row['numbers'] if 'obs_noise' in n and 'policy' in n)
  path = tmp_path / num['files'][0]
  with gzip.open(path, 'rt') as f:
    result = json.load(f)
  hit = next(r for r in result['noise_sweep']['records'] if r['policy'] == num['policy']
             and float(r['obs_noise']) == num['obs_noise'] and r['success'])
  hit['success'] = 0  # One success at that std undone; the same policy's other stds untouched.
  with gzip.open(path, 'wt') as f:
    json.dump(result, f)
  failures = pool_evals.check(str(tmp_path / 'results' / 'readme_rows.json'))
  assert any(f"{num['policy']} at obs noise {num['obs_noise']}: README {num['expect']}" in f
             for f in failures)
  # The same files' other stds (and the protocol records) still match.
  assert all(f"at obs noise {num['obs_noise']}:" in f for f in failures)


def test_swapped_readme_cells_fail_and_the_message_shows_both_sides(tmp_path):
  """Issue 102: swapping the planner and actor-prior cells of a row passed (each number was
  only looked for somewhere in the line); a changed README count was reported with the records'
  value on the README's side."""
  manifest = _copy(tmp_path)
  row = next(r for r in manifest['rows'] if r['line'] == '| door-open `weak` |')
  plan, actor = row['numbers'][0]['expect'], row['numbers'][2]['expect']
  readme = (tmp_path / 'README.md').read_text()
  line = next(l for l in readme.splitlines() if row['line'] in l)
  swapped = line.replace(f'| {plan} |', '| PLAN |').replace(f'| {actor} |', f'| {plan} |').replace(
      '| PLAN |', f'| {actor} |')
  assert swapped != line
  (tmp_path / 'README.md').write_text(readme.replace(line, swapped))
  failures = pool_evals.check(str(tmp_path / 'results' / 'readme_rows.json'))
  assert any(f'README {actor}, manifest {plan}, records {plan}' in f for f in failures), failures
  assert any(f'README {plan}, manifest {actor}, records {actor}' in f for f in failures), failures
  changed = line.replace(f'| {plan} |', '| 1/150 |')
  (tmp_path / 'README.md').write_text(readme.replace(line, changed))
  failures = pool_evals.check(str(tmp_path / 'results' / 'readme_rows.json'))
  assert failures == [f"'| door-open `weak` |', {row['numbers'][0]['policy']}: README 1/150, "
                      f'manifest {plan}, records {plan}']


def test_prose_numbers_must_appear_in_order():
  shows = pool_evals.readme_shows
  line = 'the planner keeps 137/150 at 0.05, level with BC (12 / 10, 0.83) and 0/50'
  assert shows(line, ['137/150', '12 / 10, 0.83', '0/50', '0/50']) == [
      '137/150', '12 / 10, 0.83', '0/50', '0/50']
  assert shows(line, ['12 / 10, 0.83', '137/150']) == ['12 / 10, 0.83', 'not in order']
  assert shows('solves 10/50', ['0/50']) == ['not in order']  # Bounded: not inside 10/50.
