"""Tables and curves from per-episode records; `--check` recomputes the README's numbers.

  python -m experiments.report runs/a/evaluation.json runs/b/evaluation.json   # pooled, paired
  python -m experiments.report --check=results/readme_rows.json   # README numbers vs records
  python -m experiments.report curves --workdir=runs/s0 --workdir=runs/s1 --out=curves.png
  python -m experiments.report sweeps A/ B/                        # two seed sweeps, paired
  python -m experiments.report behind sel.json ...                 # settings behind the anchor
  python -m experiments.report pack --out=DIR --workdir=RUN        # runs packed for transfer
  python -m experiments.report records --workdir=RUN --out=results/X  # a run's records, gzipped
  python -m experiments.report acting RUN/online.csv --every=40000    # who won the acting decisions

Modes: (none) pool record files; `curves`; `sweeps`; `behind`; `pack`; `records`; `acting`. `--help` lists the chosen
mode's flags.
"""

from ld_mpc_jax.cli import dispatch

MODES = {'curves': 'plot_online', 'sweeps': 'compare_sweeps', 'behind': 'where_behind', 'pack': 'pack_runs',
         'records': 'records', 'acting': 'acting'}  # mode word -> module of ld_mpc_jax.cli
DEFAULT = 'pool'
BY_FLAG = {}  # a flag that selects a mode by itself

if __name__ == '__main__':
  dispatch(__doc__, MODES, DEFAULT, BY_FLAG)
