r"""Compares planner selection settings against the actor prior, on the same held-out episodes.

  python -m experiments.evaluate selection --workdir=runs/obj/door_open_weak/seed0,... \\
      --variant=argmax: \\
      --variant=safe1:plan.safe_selection=True,plan.safe_margin=1.0 \\
      --variant=safe1_k4:plan.safe_selection=True,plan.safe_margin=1.0,plan.num_candidates=4,plan.num_prior_candidates=1 \\
      [--baselines=actor,proposal] [--episodes=50] [--seed=0] --out=runs/obj/weak_selection.json

Each workdir is one training seed (its latest checkpoint, EMA parameters). Every variant of the
planner (a name and its config overrides) and every baseline runs on the same episodes of the
held-out goals; a multi-task checkpoint runs every task. Each evaluation is cached under
<workdir>/evals/ (an interrupted comparison resumes), and the per-episode records go to --out
with a markdown table beside it (--out with .md): per variant, pooled success, the rate per
training seed, the share of decisions that departed from the actor prior's own sequence, and the
paired test against the actor prior pooled and per seed (exact McNemar; "behind" is the largest
number of episodes a seed's planner lost to its actor prior). For a multi-task checkpoint a
second table gives the same test per task (the JSON's rows_by_task); --tasks=NAME,NAME evaluates
only those of its tasks. A variant may set `eval.key_seed` (e.g. `--variant=safe1_key1:...,
eval.key_seed=1`): the same episodes with other planner draws, the planner against itself.
`--actor_variant=NAME:field=value,...` evaluates the actor prior with overrides as well, as
'actor[NAME]' (e.g. `--actor_variant=noise05:eval.action_noise=0.05`: how many of the
deterministic actor prior's successes survive noise on its actions); the anchor of the paired
tests stays the actor prior as trained.
"""

import json
import os

from absl import app, flags, logging

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import overrides
from ld_mpc_jax.analysis.selection_runs import evaluate_run

_WORKDIR = flags.DEFINE_multi_string('workdir', None, 'A training run directory, one per seed: repeat '
                                     'the flag, or separate them with commas.')
_VARIANTS = flags.DEFINE_multi_string('variant', ['argmax:'],
                                      'NAME:field=value,field=value planner settings.')
_BASELINES = flags.DEFINE_list('baselines', ['actor', 'proposal'], 'Other policies.')
_ACTOR_VARIANTS = flags.DEFINE_multi_string('actor_variant', [],
                                            'NAME:field=value,... actor-prior settings.')
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Held-out episodes per seed (and task).')
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed.')
_OUT = flags.DEFINE_string('out', None, 'JSON output; the table goes beside it (.md).')
_OVERWRITE = flags.DEFINE_bool('overwrite', False, 'Replace an existing --out file.')
_TASKS = flags.DEFINE_list('tasks', None, 'Multi-task checkpoints: only these tasks (all by '
                           'default).')
flags.mark_flags_as_required(['workdir', 'out'])


def _workdirs() -> list:
  """The run directories of every --workdir (commas separate several in one flag)."""
  return [w for item in _WORKDIR.value for w in item.split(',') if w]


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.eval import evaluation_suite
  from ld_mpc_jax.eval.run_files import git_commit
  with cli.one_line_errors():
    cli.check_new_output(_OUT.value, _OVERWRITE.value)
    variants = [overrides.parse_variant(v) for v in _VARIANTS.value]
    actor_variants = [overrides.parse_variant(v) for v in _ACTOR_VARIANTS.value]
    for flag, parsed in (('--variant', variants), ('--actor_variant', actor_variants)):
      if len({name for name, _ in parsed}) != len(parsed):
        raise ValueError(f'{flag} names must be distinct')
    missing = [w for w in _workdirs() if not os.path.isdir(w)]
    if missing:
      raise FileNotFoundError(f'no run directory {missing[0]}')
    if _TASKS.value:
      from ld_mpc_jax.learn import checkpointing
      from ld_mpc_jax.model import tasks
      for workdir in _workdirs():
        config = checkpointing.load_config(workdir)
        trained = tasks.Tasks.from_config(config)
        if not trained.multitask:
          raise ValueError(f'--tasks needs multi-task checkpoints; {workdir} holds {config.task} '
                           'alone')
        cli.check_subset('--tasks', _TASKS.value, trained.names)
  records = []
  for workdir in _workdirs():
    records.extend(evaluate_run(workdir, variants, _BASELINES.value, _EPISODES.value,
                                _SEED.value, _TASKS.value, actor_variants))
  anchor = 'actor' if 'actor' in _BASELINES.value else records[0]['policy']
  rows = evaluation_suite.against_anchor(records, anchor)
  by_task = evaluation_suite.against_anchor_by_task(records, anchor)
  md = evaluation_suite.anchor_markdown(rows, anchor)
  if by_task:
    md += '\n' + evaluation_suite.by_task_markdown(by_task, anchor)
  print(md)
  out = dict(workdirs=_workdirs(), variants=_VARIANTS.value, baselines=_BASELINES.value,
             actor_variants=_ACTOR_VARIANTS.value,
             episodes=_EPISODES.value, seed=_SEED.value, git_commit=git_commit(), rows=rows,
             rows_by_task=by_task, records=records)
  os.makedirs(os.path.dirname(os.path.abspath(_OUT.value)), exist_ok=True)
  with open(_OUT.value, 'w') as f:
    json.dump(out, f, indent=1)
  with open(os.path.splitext(_OUT.value)[0] + '.md', 'w') as f:
    f.write(md)
  print(f'wrote {_OUT.value}')
