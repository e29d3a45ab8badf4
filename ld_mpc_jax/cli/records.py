"""Copies a run's per-episode records into the repository (results/), the files behind its numbers:
each seed's episodes, periodic evaluations, acting log and losses gzipped (`seedN_episodes.csv.gz`,
...), its report, the first seed's config and the run's pooled table.

  python -m experiments.report records --workdir=runs/dense_pick_3seeds --out=results/online_pick/dense_3seeds_abc1234

A run of several seeds (`<workdir>/seed0`, ...) gives `seed0_*`, `seed1_*`, ...; a run of one seed
its files unprefixed. The gzip headers carry no name or time, so the same run packs to the same
bytes. Checkpoints, TensorBoard logs and plots stay behind. Each start of the run (resumes too)
wrote a line of `provenance.jsonl` (commit, dirty flag, command line, folder), copied beside the
records (with the run directory written `<run>` and the folder `<checkout>`, in it and in
report.md), so no command or commit is written there by hand.
"""

import gzip
import json
import os
import re
import shutil
from typing import List

from absl import flags

GZIPPED = ('episodes.csv', 'eval.csv', 'online.csv', 'losses.csv')
COPIED = ('report.md', 'provenance.jsonl')
RUN_FILES = ('pooled.md', 'pooled.json')


def _gzip(src: str, dst: str) -> None:
  with open(src, 'rb') as f, open(dst, 'wb') as raw:
    with gzip.GzipFile(filename='', mode='wb', compresslevel=9, fileobj=raw, mtime=0) as z:
      shutil.copyfileobj(f, z)


def _seed_dirs(workdir: str) -> List[str]:
  names = [n for n in os.listdir(workdir)
           if re.fullmatch(r'seed\d+', n) and os.path.isdir(os.path.join(workdir, n))]
  return sorted(names, key=lambda n: int(n[4:]))


def _copy_without_machine_paths(src: str, dst: str, workdir: str) -> None:
  """Copies a text record with this machine's paths replaced: the run directory by `<run>`, and in
  provenance.jsonl the folder the command ran in by `<checkout>` (a checkout at its `commit`)."""
  with open(src) as f:
    text = f.read().replace(os.path.abspath(workdir), '<run>')
  if src.endswith('.jsonl'):
    text = ''.join(json.dumps(dict(json.loads(line), cwd='<checkout>')) + '\n'
                   for line in text.splitlines() if line.strip())
  with open(dst, 'w') as f:
    f.write(text)


def write_records(workdir: str, out: str) -> List[str]:
  """The record files of run `workdir` written under `out` (created); their paths, sorted.

  Raises FileNotFoundError when the run has no `episodes.csv` (not finished, or not a run)."""
  seeds = _seed_dirs(workdir)
  sources = [(os.path.join(workdir, s), f'{s}_') for s in seeds] or [(workdir, '')]
  missing = [d for d, _ in sources if not os.path.isfile(os.path.join(d, 'episodes.csv'))]
  if missing:
    raise FileNotFoundError(f'{missing[0]} has no episodes.csv: the run has not reached its final '
                            'evaluation (or it is not a run directory)')
  os.makedirs(out, exist_ok=True)
  written = []
  for src, prefix in sources:
    for name in GZIPPED + COPIED:
      path = os.path.join(src, name)
      if not os.path.isfile(path):
        continue
      if name in GZIPPED:
        dst = os.path.join(out, f'{prefix}{name}.gz')
        _gzip(path, dst)
      else:
        dst = os.path.join(out, f'{prefix}{name}')
        _copy_without_machine_paths(path, dst, workdir)
      written.append(dst)
  src, prefix = sources[0]  # The first seed's config stands for the run's.
  if os.path.isfile(os.path.join(src, 'config.json')):
    written.append(os.path.join(out, f'config_{prefix.rstrip("_") or "run"}.json'))
    shutil.copyfile(os.path.join(src, 'config.json'), written[-1])
  for name in RUN_FILES if seeds else ():
    path = os.path.join(workdir, name)
    if os.path.isfile(path):
      shutil.copyfile(path, os.path.join(out, name))
      written.append(os.path.join(out, name))
  return sorted(written)


def define_flags() -> None:
  """The mode's flags (defined on use only)."""
  flags.DEFINE_string('workdir', None, 'The run directory (one seed, or seed0, seed1, ... inside).')
  flags.DEFINE_string('out', None, 'Folder for the records, e.g. results/<setting>/<name>_<commit>.')
  flags.mark_flags_as_required(['workdir', 'out'])


def main(argv):
  from ld_mpc_jax.cli import errors as cli
  with cli.one_line_errors():
    if argv[1:]:
      raise ValueError(f'unexpected arguments: {" ".join(argv[1:])}')
    if not os.path.isdir(flags.FLAGS.workdir):
      raise FileNotFoundError(f'no run directory {flags.FLAGS.workdir}')
    written = write_records(flags.FLAGS.workdir, flags.FLAGS.out)
  size = sum(os.path.getsize(p) for p in written)
  print(f'{len(written)} files, {size / 1024:.0f} KiB in {flags.FLAGS.out}')
