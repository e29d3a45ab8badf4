"""Where a planner loses the episodes its actor prior solves, by how long the actor prior took.

  python -m experiments.report behind A.json [B.json ...] [--anchor=actor] [--edges=70,90,110]

Reads per-episode records in any format `experiments.report` reads (compare_selection and
evaluate JSONs, a run's episodes.csv; each file's runs kept apart), pairs every policy with the
anchor on the same episodes, and prints one row per bin of the anchor's decisions to its first
success: how many episodes the anchor solved there and how many of them each policy failed; the
last row holds the episodes the anchor failed and how many of them each policy solved. A
per-seed deficit that sits in the anchor's slow episodes is a different failure from one spread
over all of them.
"""

from absl import app, flags

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.cli.pool import named_records, read_records
from ld_mpc_jax.eval import evaluation_suite

_ANCHOR = flags.DEFINE_string('anchor', 'actor', 'The policy the others are paired with.')
_EDGES = flags.DEFINE_list('edges', ['70', '90', '110'],
                           "Bin edges of the anchor's decisions to its first success.")
_SPLIT = flags.DEFINE_string('split', 'held_out', 'Goal split.')


def main(argv):
  paths = argv[1:]
  if not paths:
    cli.fail('give one or more evaluation files: python -m experiments.report behind A.json ...')
  with cli.one_line_errors():
    edges = [int(e) for e in _EDGES.value]
    records = named_records([{'records': read_records(p)} for p in paths], paths)
    records = [r for r in records if r.get('split', _SPLIT.value) == _SPLIT.value]
    rows = evaluation_suite.behind_by_anchor_time(records, _ANCHOR.value, edges)
  print(evaluation_suite.behind_markdown(rows, _ANCHOR.value), end='')
