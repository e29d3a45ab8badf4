"""`report records`: a run's per-episode records copied into results/, gzipped reproducibly."""

import gzip
import os
import subprocess
import sys

import pytest

from ld_mpc_jax.cli.records import write_records

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _seed(d, seed):
  os.makedirs(d / 'checkpoints', exist_ok=True)
  (d / 'episodes.csv').write_text(f'policy,episode,success\nplanner,0,{seed % 2}\n')
  (d / 'online.csv').write_text(f'env_steps,episode_success\n800,{seed}\n')
  (d / 'report.md').write_text(f'# seed {seed}\n')
  (d / 'config.json').write_text(f'{{"seed": {seed}}}')
  (d / 'checkpoints' / 'big').write_text('x' * 1000)


def test_a_run_of_three_seeds_gives_each_seeds_records_and_the_pooled_table(tmp_path):
  run = tmp_path / 'run'
  for s in (0, 1, 2):
    _seed(run / f'seed{s}', s)
  (run / 'pooled.md').write_text('| pooled |\n')
  out = tmp_path / 'results' / 'x'
  written = write_records(str(run), str(out))
  names = sorted(os.listdir(out))
  assert names == sorted(['config_seed0.json', 'pooled.md'] + [
      f'seed{s}_{n}' for s in (0, 1, 2)
      for n in ('episodes.csv.gz', 'online.csv.gz', 'report.md')])
  assert written == sorted(str(out / n) for n in names)
  with gzip.open(out / 'seed1_episodes.csv.gz', 'rt') as f:
    assert f.read() == 'policy,episode,success\nplanner,0,1\n'
  assert (out / 'config_seed0.json').read_text() == '{"seed": 0}'
  first = (out / 'seed2_online.csv.gz').read_bytes()
  write_records(str(run), str(out))  # Packed again: the same bytes (no time or name in the header).
  assert (out / 'seed2_online.csv.gz').read_bytes() == first


def test_one_seed_is_unprefixed_and_an_unfinished_run_is_refused(tmp_path):
  _seed(tmp_path / 'one', 7)
  write_records(str(tmp_path / 'one'), str(tmp_path / 'out'))
  assert sorted(os.listdir(tmp_path / 'out')) == ['config_run.json', 'episodes.csv.gz',
                                                  'online.csv.gz', 'report.md']
  _seed(tmp_path / 'two' / 'seed0', 0)
  os.makedirs(tmp_path / 'two' / 'seed1')  # Still training: no final evaluation yet.
  with pytest.raises(FileNotFoundError, match='seed1 has no episodes.csv'):
    write_records(str(tmp_path / 'two'), str(tmp_path / 'out2'))
  assert not os.path.exists(tmp_path / 'out2')


def test_the_mode_refuses_a_missing_run_in_one_line(tmp_path):
  done = subprocess.run([sys.executable, '-m', 'experiments.report', 'records', '--workdir=nope',
                         f'--out={tmp_path / "o"}'], cwd=REPO, capture_output=True, text=True,
                        timeout=120)
  assert done.returncode == 2
  assert done.stderr.strip().splitlines()[-1] == 'error: no run directory nope'
