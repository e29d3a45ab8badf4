"""Fault injection (issue 72): SIGKILL offline and online `:smoke` runs at random points, damage
random checkpoint files, and check that every run either resumes to the uninterrupted run's final
parameters or stops on one line with an intact earlier checkpoint.

  python -m benchmarks.fault_injection --kills=20 --damages=10 --disk_full=3 \
      --out=results/faults/faults.json

- References: two uninterrupted runs of each kind, the second keeping every checkpoint: whether
  they end on the same bits, and every step's state, against which the checkpoint a resume
  restores is compared; the second's wall time (compiled, its data collected) sets the range of
  the kill delays.
- Kills (`--kills` per kind): the run is killed with SIGKILL after a delay drawn uniformly over
  3-97% of the reference's wall time (so startup, acting, updates, periodic and final
  evaluation and checkpoint writes are all hit); every fourth kill instead waits a random delay,
  then kills as soon as a checkpoint write is seen in progress (orbax's temporary step folder, or
  an online buffer file without its orbax step). The same command then runs to completion.
- Damage (`--damages`, alternating kinds, alternating a completed workdir, a copy of the
  reference's, and a killed one): one file under <workdir>/checkpoints/<step>/ (the newest step
  60% of the time, else another at random) is deleted or truncated to a random length; then
  `experiments.evaluate` (1 planner episode) and the training command run on the workdir.
- Disk full (`--disk_full` per kind; needs root): the run's workdir on a tmpfs of 20-95% of the
  reference's final workdir size, so that it fills up mid-run; the run must stop on one line
  naming the full disk, its newest checkpoint with the uninterrupted run's bits; then the tmpfs
  grows (space freed) and the same command runs again, judged as a resume.
  `--disk_filled` per kind: the tmpfs is roomy, and another file fills it from a random moment
  on (0-64 KiB left), so that any write can fail; removing that file frees the space.
- Each rerun: exit code, a Python traceback in stderr or not, the warnings naming skipped steps,
  the step it resumed from, and the final TrainState (parameters, EMA parameters, optimizer
  state, step) against the reference's, leaf by leaf, exactly.

Writes one JSON row per trial to --out (rewritten after every trial, so an interrupted session
keeps what it did) and the markdown table beside it (.md); prints a summary line. The runs use
the test suite's compilation settings (tests/conftest.py: a persistent compilation cache, XLA's
optimisations mostly off), one run at a time. Stops starting trials after --max_minutes.
"""

import argparse
import json
import os
import random
import subprocess
import sys
import time
from typing import Any, Dict, List, Optional

from benchmarks import fault_cases, fault_disk
from benchmarks.fault_runner import (REPO, Runner, damage_trial, kill_trial,
                                     only_checkpoint_damaged, reference, verdict)


# ---------------------------------------------------------------------------------- records


def _cell(row: Dict[str, Any]) -> str:
  if row['identical'] is None:
    return 'n/a (stopped)'
  if row['identical']:
    return 'yes'
  return f"no (max abs diff {row['max_abs_diff']:.2g})"


def markdown(rows: List[Dict[str, Any]]) -> str:
  """The table: trial, kind, fault, point, outcome, final params identical?, traceback?"""
  lines = ['| trial | kind | fault | point | outcome | final params identical? | traceback? |',
           '| --- | --- | --- | --- | --- | --- | --- |']
  for row in rows:
    outcome = row['outcome']
    if row['rc'] == 0 and row.get('restored_step') is not None:
      outcome += (', its checkpoint as uninterrupted' if row['restored_as_reference'] else
                  ", its checkpoint NOT the uninterrupted run's")
    if row.get('skipped'):
      outcome += f" (skipped step {', '.join(map(str, row['skipped']))})"
    if row['rc'] != 0 and only_checkpoint_damaged(row):
      outcome += ', the damaged step being its only checkpoint'
    if 'disk_kib' in row:
      outcome = f"{row['first_outcome']}; after freeing space: {outcome}"
    if 'eval_rc' in row:
      outcome += (f"; evaluate: checkpoint {row['eval_checkpoint']}" if row['eval_rc'] == 0 else
                  f"; evaluate: exit {row['eval_rc']}")
    traceback = ('yes' if row['traceback'] or row.get('eval_traceback')
                 or row.get('first_traceback') or row.get('second_traceback') else 'no')
    lines.append(f"| {row['trial']} | {row['kind']} | {row['fault']} | {row['point']} | "
                 f"{outcome} | {_cell(row)} | {traceback} |")
  return '\n'.join(lines) + '\n'


def group_of(row: Dict[str, Any]) -> str:
  """'kill', 'disk full' (a small disk), 'disk filled' (by another file) or 'damage'."""
  if 'SIGKILL' in row['fault']:
    return 'kill'
  for word, group in (('SIGINT', 'interrupt'), ('second copy', 'twin'), ('crafted', 'pickle'),
                      ('--out on a full disk', 'output disk full')):
    if word in row['fault']:
      return group
  if 'disk_kib' in row:
    return 'disk filled' if 'fill_s' in row else 'disk full'
  return 'damage'


def summary(rows: List[Dict[str, Any]]) -> Dict[str, Any]:
  """Counts per kind of trial, and whether runs resumed from the same step ended alike."""
  out = {}
  for key in sorted({(r['kind'], group_of(r)) for r in rows}):
    group = [r for r in rows if (r['kind'], group_of(r)) == key]
    out[' '.join(key)] = dict(
        trials=len(group), ok=sum(r['ok'] for r in group),
        identical=sum(bool(r['identical']) for r in group),
        stopped_one_line=sum(r['rc'] != 0 and bool(r.get('one_line')) for r in group),
        tracebacks=sum(bool(r['traceback'] or r.get('eval_traceback') or r.get('first_traceback')
                            or r.get('second_traceback')) for r in group),
        checkpoint_not_as_uninterrupted=sum(r.get('restored_as_reference') is False
                                            for r in group),
        resumed_from={str(s): sum(r['resumed_from'] == s and r['rc'] == 0 for r in group)
                      for s in sorted({r['resumed_from'] for r in group})})
    if key[1].startswith('disk'):  # The run on the full disk, before the rerun.
      out[' '.join(key)].update(first_stopped_one_line=sum(r['first_stop_ok'] for r in group),
                                first_finished=sum(r['first_rc'] == 0 for r in group))
  ends = {}
  for r in rows:
    if r['final_hash']:
      ends.setdefault(f"{r['kind']} from {r['resumed_from']}", set()).add(r['final_hash'])
  out['distinct_final_states_per_resume_step'] = {k: len(v) for k, v in sorted(ends.items())}
  return out


def summary_line(rows: List[Dict[str, Any]]) -> str:
  s = summary(rows)
  parts = [f"{k}: {v['ok']}/{v['trials']} ok, " + (
      f"{v['first_stopped_one_line']} stopped on one line naming the full disk and "
      f"{v['first_finished']} finished before the disk filled; after freeing space: "
      if 'first_finished' in v else '') + f"{v['identical']} identical final states, "
           f"{v['stopped_one_line']} stopped on one line, {v['tracebacks']} tracebacks, "
           f"{v['checkpoint_not_as_uninterrupted']} restored a checkpoint unlike the "
           "uninterrupted run's"
           for k, v in s.items() if k != 'distinct_final_states_per_resume_step']
  return '; '.join(parts)


def write(out: str, header: Dict[str, Any], rows: List[Dict[str, Any]]) -> None:
  """The JSON (header, summary and rows) and the markdown table beside it, atomically."""
  os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
  with open(out + '.tmp', 'w') as f:
    json.dump(dict(header, summary=summary(rows), rows=rows), f, indent=1)
  os.replace(out + '.tmp', out)
  table = os.path.splitext(out)[0] + '.md'
  with open(table + '.tmp', 'w') as f:
    f.write(f"{header['command']}\n\n{summary_line(rows)}\n\n{markdown(rows)}")
  os.replace(table + '.tmp', table)


def parse(argv: Optional[List[str]] = None) -> argparse.Namespace:
  p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  p.add_argument('--kills', type=int, default=20, help='SIGKILLs per kind of run')
  p.add_argument('--damages', type=int, default=10, help='damaged checkpoints, kinds alternating')
  p.add_argument('--disk_full', type=int, default=3, help='runs per kind on a small tmpfs that '
                 'fills up (needs root to mount it)')
  p.add_argument('--disk_filled', type=int, default=0, help='runs per kind on a tmpfs that '
                 'another file fills from a random moment on (needs root)')
  p.add_argument('--interrupts', type=int, default=0, help='SIGINTs (Ctrl-C) per kind of run')
  p.add_argument('--twins', type=int, default=0, help='second copies on one workdir, per kind')
  p.add_argument('--pickles', type=int, default=0, help='crafted TD-MPC2 chunk files')
  p.add_argument('--outputs_full', type=int, default=0, help='evaluate/collect --out onto a full '
                 'tmpfs, alternating (needs root and the offline kind)')
  p.add_argument('--pickle_python', default=sys.executable, help='an interpreter with torch and '
                 'tensordict for --pickles (this checkout and its packages go on its path)')
  p.add_argument('--kinds', default='offline,online')
  p.add_argument('--seed', type=int, default=0)
  p.add_argument('--out', default='results/faults/faults.json')
  p.add_argument('--scratch', default='/tmp/faults', help='workdirs, logs, compilation cache')
  p.add_argument('--timeout', type=float, default=600, help='seconds per run')
  p.add_argument('--max_minutes', type=float, default=1e9, help='start no trial after this')
  p.add_argument('--retable', action='store_true', help='run nothing: the verdicts, summary '
                 'and table of the rows already in --out again (after a change to them)')
  return p.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> List[Dict[str, Any]]:
  args = parse(argv)
  if args.retable:
    with open(args.out) as f:
      records = json.load(f)
    rows = [dict(r, ok=fault_cases.VERDICTS.get(group_of(r), verdict)(r)) for r in records.pop('rows')]
    write(args.out, {k: v for k, v in records.items() if k != 'summary'}, rows)
    print(summary_line(rows))
    return rows
  start, rng = time.time(), random.Random(args.seed)
  runner = Runner(os.path.abspath(args.scratch), args.timeout)
  kinds = args.kinds.split(',')
  refs = {k: reference(runner, k) for k in kinds}
  words = sys.argv[1:] if argv is None else argv
  header = dict(command='python -m benchmarks.fault_injection ' + ' '.join(words),
                git_commit=_commit(), environment={k: runner.env[k] for k in sorted(runner.env)
                                                   if k.startswith(('JAX_', 'XLA_'))},
                references={k: {f: v for f, v in r.items() if f not in ('state',)}
                            for k, r in refs.items()})
  plan = [('kill', k, i) for k in kinds for i in range(args.kills)]
  plan += [('damage', kinds[i % len(kinds)], i) for i in range(args.damages)]
  plan += [('disk', k, i) for k in kinds for i in range(args.disk_full)]
  plan += [('filled', k, i) for k in kinds for i in range(args.disk_filled)]
  plan += [(what, k, i) for what, n in (('interrupt', args.interrupts), ('twin', args.twins))
           for k in kinds for i in range(n)]
  plan += [('pickle', 'offline', i) for i in range(args.pickles)]
  plan += [('output', 'offline', i) for i in range(args.outputs_full)]
  rows = []
  for what, kind, i in plan:
    if time.time() - start > 60 * args.max_minutes:
      header['stopped_early'] = f'--max_minutes={args.max_minutes} reached; {len(rows)} trials run'
      break
    if what in ('interrupt', 'twin', 'pickle', 'output'):
      trial = _case(what, runner, refs[kind], i, rng, args.pickle_python)
    elif what == 'kill':
      trial = kill_trial(runner, refs[kind], i, rng)
    elif what == 'disk':
      trial = fault_disk.disk_full_trial(runner, refs[kind], i, rng)
    elif what == 'filled':
      trial = fault_disk.disk_filled_trial(runner, refs[kind], i, rng)
    else:  # Per kind: completed, completed, killed, killed, ...
      trial = damage_trial(runner, refs[kind], i, rng, completed=(i // len(kinds)) % 2 == 0)
    rows.append(dict(trial=len(rows) + 1, **trial))
    print(f"{rows[-1]['trial']:3d} {kind} {rows[-1]['fault']} | {rows[-1]['point']} | "
          f"{rows[-1]['outcome']} | identical: {rows[-1]['identical']}", flush=True)
    header['minutes'] = round((time.time() - start) / 60, 1)
    write(args.out, header, rows)
  header['minutes'] = round((time.time() - start) / 60, 1)
  write(args.out, header, rows)
  print(summary_line(rows))
  return rows


def _case(what: str, runner: Runner, ref: Dict[str, Any], index: int, rng: random.Random,
          python: str) -> Dict[str, Any]:
  """A trial of issue 102's faults (benchmarks/fault_cases.py)."""
  if what == 'pickle':
    return fault_cases.pickle_trial(runner, index, python)
  if what == 'output':
    return fault_cases.output_full_trial(runner, ref, index)
  trial = fault_cases.interrupt_trial if what == 'interrupt' else fault_cases.twin_trial
  return trial(runner, ref, index, rng)


def _commit() -> Optional[str]:
  try:
    return subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=REPO, capture_output=True,
                          text=True, check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return None


if __name__ == '__main__':
  main()
