"""Trains and evaluates one config over several training seeds, and pools the results.

  python -m experiments.train --config=door_open.py:cpu --seeds=0,1,2 --eval_seeds=0,1,2

Each training seed runs the main job in <workdir>/seed<N> (default workdir:
runs/sweep/<config name>_<preset>), resuming whatever is on disk: a finished training is not
repeated, and finished evaluations are read back from their cache. Every policy is evaluated on
the same episodes (goal splits x evaluation seeds). Writes <workdir>/sweep.json (the config and
its --config.* overrides, summary and per-episode records) and sweep.md, titled with both: per
split and policy, success pooled over all episodes with a Wilson interval, the rate of each
training seed with their mean and standard deviation, and exact McNemar tests between policies
on the paired episodes.
"""

import json
import os
import sys

from absl import app, flags, logging
from ml_collections import config_flags

from ld_mpc_jax.cli import errors as cli

_CONFIG = config_flags.DEFINE_config_file('config', None, 'Config file (optionally :preset).',
                                          lock_config=True)
_SEEDS = flags.DEFINE_list('seeds', ['0', '1', '2'], 'Training seeds (config.seed).')
_EVAL_SEEDS = flags.DEFINE_list('eval_seeds', ['0', '1', '2'], 'Evaluation seeds.')
_WORKDIR = flags.DEFINE_string('workdir', None, 'Sweep directory (default: runs/sweep/<config>).')
flags.mark_flags_as_required(['config'])


def default_workdir(config_arg: str) -> str:
  """runs/sweep/<file stem>_<preset> from --config=<path>.py[:preset]."""
  path, _, preset = config_arg.partition(':')
  stem = os.path.splitext(os.path.basename(path))[0]
  return os.path.join('runs', 'sweep', f'{stem}_{preset}' if preset else stem)


def pooled_table(summary: dict) -> str:
  """Markdown: per split and policy, pooled success, Wilson CI, per-seed rates, mean +- std."""
  from ld_mpc_jax.eval.evaluation_suite import POLICY_NAMES
  lines = ['| goals | policy | pooled success | 95% CI (Wilson) | per training seed | '
           'mean +- std over seeds |', '| --- | --- | --- | --- | --- | --- |']
  for split, s in summary.items():
    for mode, p in s['policies'].items():
      lo, hi = p['success_ci95']
      runs = p['per_run']
      per = ', '.join(f'{v:.2f}' for v in runs['rates'].values())
      std = f" +- {runs['std']:.2f}" if runs['std'] is not None else ''
      lines.append(f"| {split} | {POLICY_NAMES.get(mode, mode)} | {p['successes']}/"
                   f"{p['episodes']} = {p['success_rate']:.3f} | [{lo:.3f}, {hi:.3f}] | {per} | "
                   f"{runs['mean']:.3f}{std} |")
  return '\n'.join(lines) + '\n'


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.eval import evaluation_suite, multitask_eval
  from ld_mpc_jax.model import tasks
  from ld_mpc_jax.runs.train import train_and_evaluate
  from ld_mpc_jax.configs.overrides import with_overrides
  try:
    seeds = cli.int_list('--seeds', _SEEDS.value)
    eval_seeds = tuple(cli.int_list('--eval_seeds', _EVAL_SEEDS.value))
  except ValueError as err:
    cli.fail(f'--seeds and --eval_seeds take integers ({err})')
  if _CONFIG.value.train.num_seeds != 1:  # Each --seeds entry is one run of one seed.
    cli.fail(f'--seeds runs one seed per run; drop --config.train.num_seeds='
             f'{_CONFIG.value.train.num_seeds} (or drop --seeds for N seeds in one process)')
  config_arg = os.path.basename(
      next(a for a in sys.argv if a.startswith('--config='))[len('--config='):])
  overrides = [a[len('--config.'):] for a in sys.argv if a.startswith('--config.')]
  label = config_arg + (f' ({", ".join(overrides)})' if overrides else '')
  root = _WORKDIR.value or default_workdir(config_arg)
  records = []
  for seed in seeds:
    config = with_overrides(_CONFIG.value, {'seed': seed, 'eval.seeds': eval_seeds})
    if config.eval.episodes < 1:
      cli.fail('config.eval.episodes must be >= 1 for a sweep')
    print(f'== training seed {seed}: {os.path.join(root, f"seed{seed}")}')
    report = train_and_evaluate(config, os.path.join(root, f'seed{seed}'))
    records.extend(report['records'])
  summary = evaluation_suite.summarize(records)
  text = (f'# Sweep of {label} over training seeds {", ".join(map(str, seeds))}\n\n'
          f'{config.eval.episodes} episodes per policy, goal split, evaluation seed '
          f'({", ".join(map(str, eval_seeds))}) and training seed; all policies on the same '
          'episodes.\n\n' + pooled_table(summary) + '\nPaired, pooled over all training and '
          'evaluation seeds:\n\n' + evaluation_suite.markdown(summary).split('\n\n', 1)[1])
  trained = tasks.Tasks.from_config(config)
  if trained.multitask:  # Per task, pooled over training seeds (ld_mpc_jax.model.tasks).
    names = trained.names
    text += ('\nPer task, pooled over training and evaluation seeds:\n\n'
             + multitask_eval.markdown(multitask_eval.per_task(records, names), names))
  with open(os.path.join(root, 'sweep.md'), 'w') as f:
    f.write(text)
  with open(os.path.join(root, 'sweep.json'), 'w') as f:
    json.dump({'config': config_arg, 'overrides': overrides, 'seeds': seeds,
               'eval_seeds': list(eval_seeds), 'summary': summary, 'records': records}, f, indent=1)
  print(text)
  print(f'wrote {root}/sweep.md and sweep.json')
