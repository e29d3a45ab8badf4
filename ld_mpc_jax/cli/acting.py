"""How the planner acted in online runs: the share of planned decisions each kind of candidate won.

  python -m experiments.report acting results/online_door/plan_seed0_b229cd4/online.csv.gz \
      results/online_door/dense_3seeds_83ada3e/seed0_online.csv --every=40000

Reads each run's online.csv (or its gzipped record under results/) and prints, per file, what a
run's report.md shows: the shares of its planned decisions won by each kind of candidate, that
departed from the actor prior, the candidates' spreads and the proposal's share of the elites the
refinement rounds start from (where recorded), per `--every` simulator steps and over
the whole run, each wave weighted by its planned decisions (runs.online_report.acting_summary).
"""

from absl import flags

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.cli.plot_online import read_csv
from ld_mpc_jax.runs import online_report

_EVERY = flags.DEFINE_integer('every', 10_000, 'Simulator steps per row of each table.')


def main(argv):
  paths = argv[1:]
  if not paths:
    cli.fail('give one or more online.csv files: python -m experiments.report acting '
             'RUN/online.csv ...')
  with cli.one_line_errors():
    if _EVERY.value < 1:
      raise ValueError(f'--every must be >= 1 simulator steps, got {_EVERY.value}')
    for path in paths:
      acting = online_report.acting_rows_summary(read_csv(path), _EVERY.value)
      table = online_report.acting_table(
          [(f"to {r['env_steps']:,}", r) for r in acting['spans']]
          + [('whole run', acting['whole'])], 'simulator steps')
      print(f'{path}\n\n' + ('\n'.join(table) if table else 'no planned decisions') + '\n')
