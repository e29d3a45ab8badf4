"""Benchmarking tools, apart from the model code: FLOP counts and profiles of a plan call.

Installed with the project (pyproject.toml), so that the launchers that use them
(experiments.benchmark_*, experiments.diagnose profile) run from any directory.
"""


def write_results(out: str, entries: list, table: str, quiet: bool = False) -> None:
  """Writes benchmark entries to `out` (JSON) and their markdown table beside it (.md); says so
  unless `quiet`."""
  import json
  import os
  os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
  with open(out, 'w') as f:
    json.dump(entries, f, indent=1)
  with open(os.path.splitext(out)[0] + '.md', 'w') as f:
    f.write(table)
  if not quiet:
    print(f'wrote {out} and {os.path.splitext(out)[0]}.md')
