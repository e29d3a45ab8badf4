"""Online learning curves against TD-MPC2's published per-seed curves, on the same axes.

  python -m experiments.plot_online --runs=runs/online/door_seed0 \
      --anchor=docs/anchors/tdmpc2_mw-door-open.csv --out=docs/online_door_open.png

Ours: held-out planner success of each run's periodic evaluations (`eval.csv`), with the Wilson
95% band the run computed; the per-wave exploration diagnostics (`online.csv`: training-episode
success, the largest per-step reward, which candidate kind won while acting) in a second panel.
Theirs: success against environment steps, one line per seed (docs/anchors/README.md says how
their protocol differs).
"""

import csv
import os

from absl import app, flags

from experiments import cli

FLAGS = flags.FLAGS
flags.DEFINE_list('runs', [], 'Online run workdirs (each with eval.csv and online.csv).')
flags.DEFINE_string('anchor', '', 'TD-MPC2 per-seed CSV (step,success,seed); empty: none.')
flags.DEFINE_string('out', 'online_curves.png', 'Output PNG.')
flags.DEFINE_float('max_steps', 100_000, 'Right end of the x axis (environment steps).')


def read_csv(path):
  if not os.path.exists(path):
    raise FileNotFoundError(f'{path} does not exist')
  with open(path) as f:
    return list(csv.DictReader(f))


def main(argv):
  del argv
  with cli.one_line_errors():
    if not FLAGS.runs:
      raise ValueError('--runs needs at least one run workdir')
    for run in FLAGS.runs:
      for name in ('eval.csv', 'online.csv'):
        read_csv(os.path.join(run, name))
    if FLAGS.anchor:
      read_csv(FLAGS.anchor)
  import matplotlib
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt
  fig, (ax, diag) = plt.subplots(1, 2, figsize=(12, 4))
  if FLAGS.anchor:
    rows = read_csv(FLAGS.anchor)
    for seed in sorted({r['seed'] for r in rows}):
      pts = sorted((int(r['step']), float(r['success'])) for r in rows if r['seed'] == seed)
      pts = [p for p in pts if p[0] <= FLAGS.max_steps]
      ax.plot(*zip(*pts), 's--', color='gray', alpha=0.7,
              label='TD-MPC2 (published, per seed)' if seed == min(r['seed'] for r in rows)
              else None)
  for run in FLAGS.runs:
    name = os.path.basename(os.path.normpath(run))
    ev = read_csv(os.path.join(run, 'eval.csv'))
    x = [int(float(r['step'])) for r in ev]
    ax.plot(x, [float(r['success_rate']) for r in ev], 'o-', label=f'{name}, held-out goals')
    ax.fill_between(x, [float(r['ci_lo']) for r in ev], [float(r['ci_hi']) for r in ev],
                    alpha=0.2)
    waves = read_csv(os.path.join(run, 'online.csv'))
    wx = [int(r['env_steps']) for r in waves]
    diag.plot(wx, [float(r['episode_success']) for r in waves], '.-', alpha=0.7,
              label=f'{name}: training episodes solved')
    if waves and 'won_refined' in waves[0]:
      for kind in ('proposal', 'actor_prior', 'gaussian', 'refined'):
        diag.plot(wx, [float(r[f'won_{kind}']) for r in waves], alpha=0.6,
                  label=f'{name}: {kind} won (acting)')
  ax.set_xlabel('environment steps'); ax.set_ylabel('success rate')
  ax.set_xlim(0, FLAGS.max_steps); ax.set_ylim(-0.02, 1.02); ax.legend(fontsize=8)
  diag.set_xlabel('environment steps'); diag.set_ylabel('share')
  diag.set_xlim(0, FLAGS.max_steps); diag.set_ylim(-0.02, 1.02); diag.legend(fontsize=7)
  fig.tight_layout()
  os.makedirs(os.path.dirname(os.path.abspath(FLAGS.out)), exist_ok=True)
  fig.savefig(FLAGS.out, dpi=100)
  print(f'wrote {FLAGS.out}')


if __name__ == '__main__':
  app.run(main)
