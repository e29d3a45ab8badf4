"""experiments.report curves: the tables printed beside the curves, from a run's CSVs."""

import csv

import pytest

from ld_mpc_jax.cli import plot_online


def _write(path, rows):
  with open(path, 'w', newline='') as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)


def _run(tmp_path, name, successes, won_refined):
  """A run of four waves of 800 environment steps and 4 episodes each."""
  run = tmp_path / name
  run.mkdir()
  _write(run / 'online.csv', [
      dict(env_steps=800 * (i + 1), episodes=4 * (i + 1), episode_success=s,
           max_step_reward=2.0 + i, won_proposal=0.5 if i else 'nan',
           won_refined=w if i else 'nan')
      for i, (s, w) in enumerate(zip(successes, won_refined))])
  _write(run / 'eval.csv', [dict(step=1600, episodes=10, success_rate=0.3, ci_lo=0.1, ci_hi=0.6),
                            dict(step=3200, episodes=50, success_rate=0.5, ci_lo=0.4, ci_hi=0.6)])
  return str(run)


def test_exploration_counts_the_late_waves_and_the_first_success(tmp_path):
  run = _run(tmp_path, 'a', successes=[0.0, 0.25, 0.0, 0.5], won_refined=[0, 0.2, 0.4, 0.8])
  e = plot_online.exploration(run, late_from=1600)
  assert e['first_solved'] == 1600
  assert e['late_solved'] == 0.25  # (0 * 4 + 0.5 * 4) / 8 episodes after 1600 steps.
  assert e['max_step_reward'] == 5.0
  assert e['late_won'] == {'proposal': 0.5, 'refined': pytest.approx(0.6)}
  never = plot_online.exploration(_run(tmp_path, 'b', [0.0] * 4, [0.0] * 4), late_from=1600)
  assert never['first_solved'] is None and never['late_solved'] == 0.0
  table = plot_online.exploration_table([run, str(tmp_path / 'b')], late_from=1600)
  assert '| a | 1.6k | 25% | 5.0 | proposal 50%, refined 60% |' in table
  assert '| b | none | 0% |' in table


def test_curve_table_pools_the_steps_every_run_reached(tmp_path):
  runs = [_run(tmp_path, n, [0.0] * 4, [0.0] * 4) for n in ('a', 'b')]
  table = plot_online.curve_table(runs)
  assert '| 3k | 25/50 | 25/50 | 50/100 = 0.50 |' in table
  assert '| 2k | 3/10 | 3/10 | 6/20 = 0.30 |' in table


def test_tdmpc2_steps_are_doubled_to_simulator_steps(tmp_path):
  """TD-MPC2 counts decisions at action repeat 2: its step 100000 is drawn at x = 200000."""
  anchor = tmp_path / 'anchor.csv'
  _write(anchor, [dict(step=s, success=v, seed=seed)
                  for seed in (1, 2) for s, v in ((0, 0.0), (100000, 0.7), (200000, 0.9))])
  assert plot_online.anchor_curves(str(anchor), max_steps=200_000) == {
      '1': [(0, 0.0), (200000, 0.7)], '2': [(0, 0.0), (200000, 0.7)]}
  run = _run(tmp_path, 'a', [0.0] * 4, [0.0] * 4)
  fig = plot_online.draw([run], str(anchor), max_steps=400_000)
  ax, diag = fig.axes
  theirs = [l for l in ax.lines if l.get_color() == 'gray']
  assert [list(l.get_xdata()) for l in theirs] == [[0, 200000, 400000]] * 2
  assert [list(l.get_ydata()) for l in theirs] == [[0.0, 0.7, 0.9]] * 2
  ours = [l for l in ax.lines if l.get_color() != 'gray']
  assert [list(l.get_xdata()) for l in ours] == [[1600, 3200]]  # our steps are drawn as logged
  assert ax.get_xlabel() == diag.get_xlabel() == 'simulator steps'
  assert ax.get_xlim() == (0, 400_000)
  # At the default 100k simulator steps TD-MPC2 has only its point at 0.
  fig = plot_online.draw([run], str(anchor), max_steps=100_000)
  assert [list(l.get_xdata()) for l in fig.axes[0].lines if l.get_color() == 'gray'] == [[0]] * 2


def test_committed_records_named_by_a_prefix_read_like_their_run(tmp_path):
  import gzip, shutil  # pylint: disable=g-import-not-at-top,multiple-imports
  run = _run(tmp_path, 'a', [0.0, 0.25, 0.0, 0.5], [0.0] * 4)
  (tmp_path / 'records').mkdir()
  for name in ('eval.csv', 'online.csv'):  # As results/ keeps them: seed0_eval.csv.gz, ...
    with open(f'{run}/{name}', 'rb') as src, gzip.open(tmp_path / 'records' / f'seed0_{name}.gz',
                                                       'wb') as dst:
      shutil.copyfileobj(src, dst)
  prefix = str(tmp_path / 'records' / 'seed0_')
  assert plot_online.run_name(prefix) == 'records seed0'
  ours, theirs = (plot_online.curve_table([r]).splitlines()[2:] for r in (prefix, run))
  assert ours == theirs and '| 3k | 25/50 |' in ours[1]
  assert plot_online.exploration(prefix, 1600) == plot_online.exploration(run, 1600)


def test_runs_of_two_folders_are_pooled_apart(tmp_path):
  """The seeds of a sparse run and of a dense run, named together: one pooled column each, not
  one pool of all six."""
  runs = []
  for group, rate in (('sparse', 0.2), ('dense', 0.6)):
    (tmp_path / group).mkdir()
    for s in range(3):
      runs.append(_run(tmp_path / group, f'seed{s}', [0.0] * 4, [0.0] * 4))
      _write(tmp_path / group / f'seed{s}' / 'eval.csv',
             [dict(step=3200, episodes=50, success_rate=rate, ci_lo=0, ci_hi=1)])
  head, _, row = plot_online.curve_table(runs).splitlines()
  assert head.endswith('| pooled sparse | 95% CI | pooled dense | 95% CI |')
  assert row.startswith('| 3k | 10/50 | 10/50 | 10/50 | 30/50 | 30/50 | 30/50 | 30/150 = 0.20 |')
  assert '| 90/150 = 0.60 |' in row
  assert plot_online.curve_table(runs[:3]).splitlines()[0].endswith('| pooled | 95% CI (Wilson) |')


def test_pooled_curves_draw_one_line_per_run_of_seeds_with_its_wilson_band(tmp_path):
  """--pooled: the seeds of each run become one curve of pooled successes (at the steps all
  seeds reached) and one line of training episodes solved (the seeds' mean per wave)."""
  from ld_mpc_jax.ops import stats  # pylint: disable=g-import-not-at-top
  runs = []
  for group, rates in (('sparse', (0.2, 0.4, 0.6)), ('dense', (0.6, 0.6, 0.6))):
    (tmp_path / group).mkdir()
    for s, rate in enumerate(rates):
      runs.append(_run(tmp_path / group, f'seed{s}', [0.0, 0.25 * s, 0.5, 1.0], [0.0] * 4))
      _write(tmp_path / group / f'seed{s}' / 'eval.csv',
             [dict(step=1600, episodes=10, success_rate=rate, ci_lo=0, ci_hi=1)]
             + ([dict(step=3200, episodes=50, success_rate=rate, ci_lo=0, ci_hi=1)] if s else []))
  curves = plot_online.pooled_curves(runs)
  sparse, dense = str(tmp_path / 'sparse'), str(tmp_path / 'dense')
  assert [p[:3] for p in curves[sparse]] == [(2000, 12, 30)]  # 3200: seed 0 never reached it.
  assert curves[sparse][0][3:] == pytest.approx(stats.wilson_interval(12, 30))
  assert [p[:3] for p in curves[dense]] == [(2000, 18, 30)]
  waves = plot_online.pooled_waves(runs)
  assert waves[sparse] == [(800, 0.0), (1600, 0.25), (2400, 0.5), (3200, 1.0)]
  fig = plot_online.draw(runs, '', max_steps=4000, pooled=True)
  ax, diag = fig.axes
  assert [list(l.get_ydata()) for l in ax.lines] == [[0.4], [0.6]]
  assert [l.get_label() for l in ax.lines][0] == 'sparse (3 seeds pooled), held-out goals'
  assert len(ax.collections) == 2 and len(diag.lines) == 2  # a band and a wave line per group
  assert len(plot_online.draw(runs, '', max_steps=4000).axes[0].lines) == 6  # per seed
