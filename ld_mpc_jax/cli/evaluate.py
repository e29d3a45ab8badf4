"""Evaluates a trained LD-MPC checkpoint under the Meta-World protocol, on held-out and train goals.

  python -m experiments.evaluate --workdir=runs/door_open_cpu --seeds=0,1,2
      [--modes=plan,actor,proposal] [--splits=held_out,train] [--config.plan.warm_start_steps=0]
  python -m experiments.evaluate --workdir=runs/mt10_cpu    # a multi-task run: every task

Loads <workdir>/config.json and the latest checkpoint (EMA parameters) and runs every policy on
the same episodes of each goal split and evaluation seed (environments in lockstep, one jitted
call per decision). Prints pooled success with Wilson intervals and exact McNemar tests between
policies, and writes the per-episode records and the summary to <workdir>/evaluation.json
(or --out; an existing file is kept unless --overwrite; written once the policies are evaluated,
then again with the noise sweep and video). Each (policy, split, seed) result is kept under
<workdir>/evals/ as training keeps its own, so a killed evaluation resumes where it stopped and
a finished one is read back (--nocache: recompute every cell, keep none).
Optionally an observation-noise sweep (--noise_sweep: every policy of --modes at each std of
eval.noise_stds on the same held-out episodes, noise on eval.obs_noise_dims; <out>_noise.md and
<out>_noise.png beside the JSON, whose `noise_sweep` keeps the per-episode records; pool three
training seeds' JSONs with experiments.report) and a short video (mp4 with imageio-ffmpeg;
rendering needs MUJOCO_GL=osmesa and libosmesa6 on a headless machine).
"""

import json
import os
import sys

from absl import app, flags, logging

from ld_mpc_jax.cli import errors as cli

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training run directory.')
_MODES = flags.DEFINE_list('modes', ['plan', 'actor', 'proposal'], 'Policies to evaluate.')
_SPLITS = flags.DEFINE_list('splits', ['held_out', 'train'], 'Goal splits, held_out first.')
_SEEDS = flags.DEFINE_list('seeds', ['0'], 'Evaluation seeds (pooled).')
MAX_EPISODES = 100_000  # Per policy, split and seed: days of evaluation here already.
_EPISODES = flags.DEFINE_integer('episodes', None, 'Episodes per policy, split and seed '
                                 '(default: config).')
_NOISE = flags.DEFINE_bool('noise_sweep', False, 'Observation-noise sweep of every --modes '
                            'policy at eval.noise_stds (held-out goals): table and plot.')
_VIDEO = flags.DEFINE_bool('video', False, 'Render a 2-episode video of the planner.')
_OUT = flags.DEFINE_string('out', None, 'JSON output (default: <workdir>/evaluation.json).')
_VIDEO_OUT = flags.DEFINE_string('video_out', None, 'mp4 of --video (default: '
                                  '<workdir>/planner.mp4).')
_CACHE = flags.DEFINE_bool('cache', True, 'Keep each (policy, split, seed) result under '
                           '<workdir>/evals/ and reuse it, as training does: a killed evaluation '
                           'resumes where it stopped (--nocache: recompute all, write none).')
_OVERWRITE = flags.DEFINE_bool('overwrite', False, 'Replace an existing --out or --video_out '
                               'file.')
flags.mark_flag_as_required('workdir')


OVERRIDES = []  # 'field=value' items of --config.field=value (ld_mpc_jax.cli.dispatch).


def _checked_seeds() -> list:
  """--seeds as integers, after checking --episodes (before any work)."""
  if _EPISODES.value is not None and not 1 <= _EPISODES.value <= MAX_EPISODES:
    raise ValueError(f'--episodes must be between 1 and {MAX_EPISODES:,}, got {_EPISODES.value}')
  return cli.int_list('--seeds', _SEEDS.value)


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.eval import evaluation_suite, multitask_eval
  from ld_mpc_jax.eval.spec import EvalSpec
  from ld_mpc_jax.runs.checks import validate_config
  from ld_mpc_jax.eval.run_files import git_commit
  from ld_mpc_jax.runs.loop import run_evaluation
  from ld_mpc_jax.configs.overrides import parse_items, with_overrides
  with cli.one_line_errors():
    seeds = _checked_seeds()
    path = _OUT.value or os.path.join(_WORKDIR.value, 'evaluation.json')
    cli.check_new_output(path, _OVERWRITE.value)  # Before the long work: exists, or unwritable.
    video = _VIDEO_OUT.value or os.path.join(_WORKDIR.value, 'planner.mp4')
    if _VIDEO.value:
      cli.check_new_output(video, _OVERWRITE.value, flag='--video_out')
    cli.check_subset('--splits', _SPLITS.value, ['held_out', 'train'])
    cli.check_subset('--modes', _MODES.value, ['plan', 'actor', 'proposal', 'mppi'])
    config, params, step = run_checks.load_for_evaluation(_WORKDIR.value)
    config = with_overrides(config, parse_items(OVERRIDES))
    validate_config(config)
    spec = EvalSpec.from_config(config)
    splits, evaluate = multitask_eval.grid(spec, _SPLITS.value)  # No train split for
    if splits != tuple(_SPLITS.value):  # TD-MPC2 data: its goals were random per episode.
      print(f'goal splits {list(splits)} only: the data were not collected on MT1 goals')
  episodes = _EPISODES.value or config.eval.episodes
  print(f'evaluating checkpoint step {step} of {_WORKDIR.value}: {", ".join(_MODES.value)}; '
        f'{episodes} per split {list(splits)} and seed {seeds}', file=sys.stderr, flush=True)
  records = evaluate(spec, params, _cache_dir(), step, _MODES.value, splits, seeds, episodes,
                     run=config.seed)  # A multi-task agent: every task, records per task.
  summary = evaluation_suite.summarize(records)
  if spec.multitask:
    names = spec.task_names
    print(multitask_eval.markdown(multitask_eval.per_task(records, names), names))
  print(evaluation_suite.markdown(summary))
  out = {'step': step, 'episodes': episodes, 'seeds': seeds, 'overrides': OVERRIDES,
         'git_commit': git_commit(), 'summary': summary, 'records': records}
  _write(path, out)  # The records are kept should the extras below fail.
  if _NOISE.value:  # Every policy of --modes at every eval.noise_stds, held-out goals.
    out['noise_sweep'] = _noise_sweep(spec, params, step, seeds, episodes,
                                      config.eval.noise_stds, path, run=config.seed)
  if _VIDEO.value:
    try:  # `video`: its own name; `path` is the JSON's.
      video = run_evaluation(spec, params, 'plan', 2, seeds[0], video_path=video)['video_path']
      out['video'] = video
      print(f'video: {video}')
    except Exception as err:  # pylint: disable=broad-except
      out['video_error'] = f'{type(err).__name__}: {err}'
      print(f'no video ({out["video_error"]}); try MUJOCO_GL=osmesa with libosmesa6 installed')
  _write(path, out)
  print(f'wrote {path} and {os.path.splitext(path)[0]}.md')


def _cache_dir():
  """The workdir whose evals/ keeps each evaluated cell, or None (--nocache, or a run directory
  this user cannot write: nothing is kept, with a line saying so)."""
  if not _CACHE.value:
    return None
  if not os.access(_WORKDIR.value, os.W_OK):
    print(f'{_WORKDIR.value} is not writable: the evaluation keeps no cells under evals/',
          file=sys.stderr)
    return None
  return _WORKDIR.value


def _noise_sweep(spec, params, step: int, seeds, episodes: int, stds, path: str, run) -> dict:
  """Every policy of --modes at each observation-noise std of `stds` on held-out goals: the
  output's entry, with its table and plot beside `path` (<out>_noise.md, <out>_noise.png)."""
  from ld_mpc_jax.analysis import noise_sweep  # pylint: disable=g-import-not-at-top
  records = noise_sweep.run_sweep(spec, params, _WORKDIR.value, step, _MODES.value, seeds,
                                  episodes, stds, run=run)
  rows = noise_sweep.table(records)
  stem, dims = os.path.splitext(path)[0], spec.eval.obs_noise_dims
  with open(stem + '_noise.md', 'w') as f:
    f.write(noise_sweep.markdown(rows))
  noise_sweep.plot(rows, stem + '_noise.png', f'{spec.task}, noise on {dims} dimensions')
  print(noise_sweep.markdown(rows) + f'wrote {stem}_noise.md and {stem}_noise.png')
  return dict(dims=dims, rows=rows, records=records)


def _write(path: str, out: dict) -> None:
  """`out` as JSON at `path`, and its tables as markdown beside it (.md), atomically (a file that
  exists is always whole). A write that fails (a full disk) is one line, exit code 1, and leaves
  no partial file."""
  from ld_mpc_jax.eval import evaluation_suite  # pylint: disable=g-import-not-at-top
  md = os.path.splitext(path)[0] + '.md'
  texts = [(path, json.dumps(out, indent=1)),
           (md, f"Evaluation at step {out['step']}, {out['episodes']} episodes per policy, goal "
                f"split and evaluation seed (seeds {out['seeds']}); git commit "
                f"{out['git_commit']}.\n\n{evaluation_suite.markdown(out['summary'])}\n")]
  try:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    for target, text in texts:
      with open(target + '.tmp', 'w') as f:
        f.write(text)
      os.replace(target + '.tmp', target)
  except OSError as err:
    for target, _ in texts:
      if os.path.exists(target + '.tmp'):
        os.remove(target + '.tmp')
    print(f'error: could not write {path}: {err.strerror or err}', file=sys.stderr)
    sys.exit(1)
