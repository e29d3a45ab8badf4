r"""Online learning curves against TD-MPC2's published per-seed curves, on the same axes.

  python -m experiments.report curves --workdir=runs/online/door_seed0 \
      --anchor=docs/anchors/tdmpc2_mw-door-open.csv --out=online_door_open.png

Ours: held-out planner success of each run's periodic evaluations (`eval.csv`), with the Wilson
95% band the run computed; the per-wave exploration diagnostics (`online.csv`: training-episode
success, the largest per-step reward, which candidate kind won while acting) in a second panel.
Theirs: success against simulator steps, one line per seed. Their step column counts decisions
and their Meta-World wrapper repeats each action twice, so it is doubled: their 100k decisions are
drawn at our 200k simulator steps (pass --max_steps=400000 to see their published points after 0).
docs/anchors/README.md says how their protocol differs.
"""

import csv
import glob
import gzip
import os

from absl import app, flags

from ld_mpc_jax.cli import errors as cli

FLAGS = flags.FLAGS


def define_flags() -> None:
  """The mode's flags (defined on use only: tests import this module beside other flags)."""
  flags.DEFINE_multi_string('workdir', [], 'An online run directory (with eval.csv and '
                            'online.csv), or the prefix of committed records (.../seed0_ for '
                            'seed0_eval.csv[.gz]); repeat the flag, or separate with commas.')
  flags.DEFINE_string('anchor', '', 'TD-MPC2 per-seed CSV (step,success,seed); empty: none.')
  flags.DEFINE_string('out', 'online_curves.png', 'Output PNG.')
  flags.DEFINE_float('max_steps', 100_000, 'Right end of the x axis (simulator steps).')
  flags.DEFINE_integer('late_from', 80_000, 'The exploration table averages the waves after '
                       'this many environment steps.')
  flags.DEFINE_bool('pooled', False, 'Draw one curve per group of runs (the seeds of one run, '
                    'see run_group): successes pooled over its seeds with their Wilson band, '
                    'instead of a curve per seed.')


def read_csv(path):
  """Rows of a CSV file, or of its gzipped copy `path`.gz (committed records)."""
  if not os.path.exists(path) and os.path.exists(path + '.gz'):
    path += '.gz'
  if not os.path.exists(path):
    raise FileNotFoundError(f'{path} does not exist')
  with (gzip.open(path, 'rt') if path.endswith('.gz') else open(path)) as f:
    return list(csv.DictReader(f))


def run_file(run: str, name: str) -> str:
  """`name` of a run: <run>/<name> for a run directory, else <run><name> for committed records
  named by a prefix (results/.../seed0_ -> seed0_eval.csv[.gz])."""
  return os.path.join(run, name) if os.path.isdir(run) else run + name


def run_name(run: str) -> str:
  """A run's label: its directory's name, or a records prefix's folder and seed."""
  if os.path.isdir(run):
    return os.path.basename(os.path.normpath(run))
  return f'{os.path.basename(os.path.dirname(run))} {os.path.basename(run).rstrip("_")}'


def _workdirs() -> list:
  """The run directories of every --workdir (commas separate several in one flag)."""
  return [w for item in FLAGS.workdir for w in item.split(',') if w]


def main(argv):
  del argv
  with cli.one_line_errors():
    if not _workdirs():
      raise ValueError('name at least one run with --workdir')
    for run in _workdirs():
      if not os.path.isdir(run) and not glob.glob(glob.escape(run) + 'eval.csv*'):
        raise ValueError(f'--workdir={run}: no run directory, nor records {run}eval.csv[.gz]')
      for name in ('eval.csv', 'online.csv'):
        read_csv(run_file(run, name))
    if FLAGS.anchor:
      read_csv(FLAGS.anchor)
  fig = draw(_workdirs(), FLAGS.anchor, FLAGS.max_steps, pooled=FLAGS.pooled)
  os.makedirs(os.path.dirname(os.path.abspath(FLAGS.out)), exist_ok=True)
  fig.savefig(FLAGS.out, dpi=100)
  print(f'wrote {FLAGS.out}')
  print(curve_table(_workdirs()))
  print()
  print(exploration_table(_workdirs(), FLAGS.late_from))


# TD-MPC2's Meta-World wrapper repeats each action twice and its step column counts decisions.
TDMPC2_ACTION_REPEAT = 2


def anchor_curves(path: str, max_steps: float) -> dict:
  """TD-MPC2's published per-seed curves in this project's unit: {seed: [(simulator steps,
  success)]}, sorted by step, the points beyond `max_steps` simulator steps left out. Their
  `step` column counts decisions, so it is multiplied by `TDMPC2_ACTION_REPEAT`."""
  rows = read_csv(path)
  curves = {}
  for seed in sorted({r['seed'] for r in rows}):
    pts = sorted((int(r['step']) * TDMPC2_ACTION_REPEAT, float(r['success']))
                 for r in rows if r['seed'] == seed)
    curves[seed] = [p for p in pts if p[0] <= max_steps]
  return curves


def draw(runs, anchor: str, max_steps: float, pooled: bool = False):
  """The figure: held-out success per run against simulator steps (with TD-MPC2's curves from
  `anchor` when not empty) on the left, the per-wave exploration diagnostics on the right. With
  `pooled`, one curve per group of runs (`pooled_curves`, `pooled_waves`) instead of one per run."""
  import matplotlib
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt
  fig, (ax, diag) = plt.subplots(1, 2, figsize=(12, 4))
  for i, pts in enumerate((anchor_curves(anchor, max_steps) if anchor else {}).values()):
    if pts:
      ax.plot(*zip(*pts), 's--', color='gray', alpha=0.7,
              label=None if i else 'TD-MPC2 (published, per seed)')
  (_draw_pooled if pooled else _draw_per_run)(ax, diag, runs)
  ax.set_xlabel('simulator steps'); ax.set_ylabel('success rate')
  ax.set_xlim(0, max_steps); ax.set_ylim(-0.02, 1.02); ax.legend(fontsize=8)
  diag.set_xlabel('simulator steps'); diag.set_ylabel('share')
  diag.set_xlim(0, max_steps); diag.set_ylim(-0.02, 1.02); diag.legend(fontsize=7)
  fig.tight_layout()
  return fig


def _draw_per_run(ax, diag, runs) -> None:
  """One curve per run: its held-out success with the Wilson band it logged, its training
  episodes solved per wave and, where logged, how often a refined candidate won while acting."""
  for i, run in enumerate(runs):
    name, color = run_name(run), f'C{i}'
    ev = read_csv(run_file(run, 'eval.csv'))
    x = [int(float(r['step'])) for r in ev]
    ax.plot(x, [float(r['success_rate']) for r in ev], 'o-', color=color,
            label=f'{name}, held-out goals')
    ax.fill_between(x, [float(r['ci_lo']) for r in ev], [float(r['ci_hi']) for r in ev],
                    color=color, alpha=0.15)
    waves = read_csv(run_file(run, 'online.csv'))
    wx = [int(r['env_steps']) for r in waves]
    diag.plot(wx, [float(r['episode_success']) for r in waves], '-', color=color,
              label=f'{name}: training episodes solved')
    if waves and 'won_refined' in waves[0]:
      diag.plot(wx, [float(r['won_refined']) for r in waves], ':', color=color,
                label=f'{name}: refined candidate won (acting)')


def _draw_pooled(ax, diag, runs) -> None:
  """One curve per group of `runs`: pooled held-out success with its Wilson band, and the
  training episodes solved per wave (mean over the group's seeds)."""
  curves, waves = pooled_curves(runs), pooled_waves(runs)
  for i, (group, members) in enumerate(_groups(runs).items()):
    name, color = f'{os.path.basename(group) or group} ({len(members)} seeds pooled)', f'C{i}'
    pts = curves[group]
    x = [p[0] for p in pts]
    ax.plot(x, [p[1] / p[2] for p in pts], 'o-', color=color, label=f'{name}, held-out goals')
    ax.fill_between(x, [p[3] for p in pts], [p[4] for p in pts], color=color, alpha=0.15)
    wx = [w[0] for w in waves[group]]
    diag.plot(wx, [w[1] for w in waves[group]], '-', color=color,
              label=f'{name}: training episodes solved')


def _groups(runs) -> dict:
  """{run_group: [its runs]}, in the order the runs are named."""
  groups = {}
  for run in runs:
    groups.setdefault(run_group(run), []).append(run)
  return groups


def _eval_counts(run: str) -> dict:
  """{evaluation step (rounded to 1,000): (successes, episodes)} of a run's `eval.csv`."""
  counts = {}
  for r in read_csv(run_file(run, 'eval.csv')):
    n = int(r['episodes'])
    counts[round(int(float(r['step'])), -3)] = (round(float(r['success_rate']) * n), n)
  return counts


def pooled_curves(runs) -> dict:
  """{run_group: [(step, successes, episodes, Wilson low, Wilson high)]}: held-out successes
  pooled over the runs of each group, at the evaluation steps every one of them reached."""
  from ld_mpc_jax.ops import stats
  out = {}
  for group, members in _groups(runs).items():
    counts = [_eval_counts(run) for run in members]
    steps = sorted(set.intersection(*(set(c) for c in counts)))
    out[group] = []
    for step in steps:
      k, n = sum(c[step][0] for c in counts), sum(c[step][1] for c in counts)
      out[group].append((step, k, n, *stats.wilson_interval(k, n)))
  return out


def pooled_waves(runs) -> dict:
  """{run_group: [(environment steps, share of training episodes solved)]}: the mean over the
  group's runs of each wave's `episode_success`, at the wave ends every run reached."""
  out = {}
  for group, members in _groups(runs).items():
    per_run = [{int(r['env_steps']): float(r['episode_success'])
                for r in read_csv(run_file(run, 'online.csv'))} for run in members]
    steps = sorted(set.intersection(*(set(w) for w in per_run)))
    out[group] = [(s, sum(w[s] for w in per_run) / len(per_run)) for s in steps]
  return out


def run_group(run: str) -> str:
  """The group a run is pooled in: the folder holding it (a run of several seeds keeps each seed
  in `<run>/seed<s>`, and committed records name each seed by a prefix in one folder)."""
  return os.path.dirname(os.path.normpath(run))


def curve_table(runs) -> str:
  """Markdown: held-out planner successes per run at each evaluation, and pooled over the runs
  of each group (`run_group`: the seeds of one run) at the steps all of them reached (Wilson 95%
  interval). Runs from several groups (sparse against dense, say) get a pooled column each."""
  per_run = {}
  for run in runs:
    for step, counts in _eval_counts(run).items():
      per_run.setdefault(step, {})[run] = counts
  groups = _groups(runs)
  pooled = {g: {p[0]: p[1:] for p in pts} for g, pts in pooled_curves(runs).items()}
  names = [run_name(r) for r in runs]
  pooled_names = (['pooled | 95% CI (Wilson)'] if len(groups) == 1 else
                  [f'pooled {os.path.basename(g) or g} | 95% CI' for g in groups])
  lines = ['| environment steps | ' + ' | '.join(names + pooled_names) + ' |',
           '| --- |' + ' --- |' * (len(runs) + 2 * len(groups))]
  for step in sorted(per_run):
    cells = [per_run[step].get(run) for run in runs]
    shown = [f'{c[0]}/{c[1]}' if c else '-' for c in cells]
    for group in groups:
      if step in pooled[group]:
        k, n, lo, hi = pooled[group][step]
        shown += [f'{k}/{n} = {k / n:.2f}', f'[{lo:.2f}, {hi:.2f}]']
      else:
        shown += ['-', '-']
    lines.append(f'| {step // 1000}k | ' + ' | '.join(shown) + ' |')
  return '\n'.join(lines)


CANDIDATE_KINDS = ('proposal', 'actor_prior', 'gaussian', 'refined')


def exploration(run: str, late_from: int) -> dict:
  """One run's exploration diagnostics from its `online.csv` (one row per wave of acting):
  `first_solved` (the environment steps at the end of the first wave with a solved training
  episode, None if none), `late_solved` (the share of training episodes solved in the waves
  after `late_from` steps, weighted by each wave's episodes; None if none), `max_step_reward`
  (the largest reward of one decision) and `late_won` (per candidate kind, the mean share of the
  acting decisions it won in those waves; kinds the run did not log are left out)."""
  waves = read_csv(run_file(run, 'online.csv'))
  first = next((int(r['env_steps']) for r in waves if float(r['episode_success']) > 0), None)
  solved = episodes = 0.0
  previous, late = 0, []
  for r in waves:
    n, previous = int(r['episodes']) - previous, int(r['episodes'])
    if int(r['env_steps']) > late_from:
      solved, episodes = solved + float(r['episode_success']) * n, episodes + n
      late.append(r)
  won = {}
  for kind in CANDIDATE_KINDS:
    shares = [float(r[f'won_{kind}']) for r in late
              if r.get(f'won_{kind}') not in (None, '', 'nan')]
    if shares:
      won[kind] = sum(shares) / len(shares)
  return dict(first_solved=first, late_solved=solved / episodes if episodes else None,
              max_step_reward=max((float(r['max_step_reward']) for r in waves), default=None),
              late_won=won)


def exploration_table(runs, late_from: int) -> str:
  """Markdown: `exploration` of each run, one row per run."""
  late = f'{late_from // 1000}k'
  lines = [f'| run | first solved training episode | training episodes solved after {late} | '
           f'largest reward of one decision | acting decisions won after {late} |',
           '| --- | --- | --- | --- | --- |']
  for run in runs:
    e = exploration(run, late_from)
    first = f'{e["first_solved"] / 1000:.1f}k' if e['first_solved'] is not None else 'none'
    share = f'{e["late_solved"]:.0%}' if e['late_solved'] is not None else '-'
    reward = f'{e["max_step_reward"]:.1f}' if e['max_step_reward'] is not None else '-'
    won = ', '.join(f'{k} {v:.0%}' for k, v in e['late_won'].items()) or '-'
    lines.append(f'| {run_name(run)} | {first} | {share} | {reward} | '
                 f'{won} |')
  return '\n'.join(lines)
