"""The ablation table: six model variants and three baselines on door-open-v3, measured.

  python -m experiments.train ablations --workdir=runs/ablations    # about two hours on 2 CPU cores

Trains every variant with the same main job (ld_mpc_jax.runs.train.train_and_evaluate, preset
door_open.py:ablation) on the `mixed` dataset over --seeds training seeds and on the `expert`
dataset over one seed, evaluates each with the Meta-World protocol (50 episodes), then writes
<workdir>/ablations.md (table), ablations.json and ablations.png (bar plot), and an
observation-noise sweep of the full model and the two strongest baselines.

Variants (ld_mpc_jax.model.models):
  1 mlp_mlp          single-step Gaussian MLP proposal + MLP dynamics
  2 diffstep_mlp     single-step diffusion proposal + MLP dynamics
  3 diffseq_mlp      whole-sequence diffusion proposal + MLP dynamics
  4 diffseq_traj     whole-sequence diffusion proposal + whole-trajectory latent diffusion
  5 ldmpc            the full model: autoregressive latent diffusion dynamics
  6 ldmpc_guided     the full model with energy-guided proposal sampling
Variant 6 differs from 5 only at planning time, so it is evaluated on variant 5's checkpoints.
Baselines on the same checkpoints as 5: the actor prior alone, the diffusion proposal alone, and
MPPI on the learned model (config.mppi).

Every finished piece is a JSON file on disk and is skipped when the sweep is run again; an
interrupted training resumes from its last checkpoint, so a half-finished sweep picks up where
it stopped.
"""

import json
import os
import sys
import time

from absl import app, flags, logging
from ml_collections import config_flags
import numpy as np
import scipy.stats

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.configs import CONFIG_DIR
from ld_mpc_jax.configs.overrides import with_overrides
from ld_mpc_jax.cli.pool import read_records
from ld_mpc_jax.ops import stats

VARIANTS = {  # name -> (label, config overrides, checkpoint of another variant to reuse).
    'mlp_mlp': ('1 MLP proposal (1-step) + MLP dynamics',
                {'model.proposal_type': 'mlp', 'model.dynamics_type': 'mlp'}, None),
    'diffstep_mlp': ('2 diffusion proposal (1-step) + MLP dynamics',
                     {'model.proposal_type': 'diffusion_step', 'model.dynamics_type': 'mlp'},
                     None),
    'diffseq_mlp': ('3 diffusion proposal (sequence) + MLP dynamics',
                    {'model.dynamics_type': 'mlp'}, None),
    'diffseq_traj': ('4 diffusion proposal + trajectory latent diffusion',
                     {'model.dynamics_type': 'diffusion_traj',
                      'critic.latent_rollout': False}, None),
    'ldmpc': ('5 LD-MPC (autoregressive latent diffusion)', {}, None),
    'ldmpc_guided': ('6 LD-MPC + energy guidance', {'plan.guidance_scale': 0.2}, 'ldmpc'),
}
BASELINES = {  # name -> (label, evaluation mode on the 'ldmpc' checkpoints).
    'actor': ('actor prior alone', 'actor'),
    'proposal': ('diffusion proposal alone', 'proposal'),
    'mppi': ('MPPI on the learned model', 'mppi'),
}

_CONFIG = config_flags.DEFINE_config_file(
    'config', os.path.join(CONFIG_DIR, 'door_open.py') + ':ablation',
    'Base config (optionally :preset) every variant overrides.', lock_config=False)
_WORKDIR = flags.DEFINE_string('workdir', 'runs/ablations', 'Sweep directory.')
_SEEDS = flags.DEFINE_integer('seeds', 3, 'Training seeds on the mixed dataset.')
_EXPERT = flags.DEFINE_bool('expert', True, 'Also one seed on the expert dataset.')
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Evaluation episodes per policy.')
_VARIANTS = flags.DEFINE_list('variants', list(VARIANTS), f'Subset of {list(VARIANTS)}.')
_NOISE = flags.DEFINE_bool('noise_sweep', True, 'Observation-noise sweep at the end.')


def seed_interval(values) -> list:
  """95% Student-t interval of the mean over seeds (a point for one seed), clipped to [0, 1]."""
  values = np.asarray(values, float)
  if len(values) < 2:
    return [float(values.mean())] * 2
  lo, hi = scipy.stats.t.interval(0.95, len(values) - 1, loc=values.mean(),
                                  scale=scipy.stats.sem(values))
  return [max(0.0, float(lo)), min(1.0, float(hi))]


def runs(seeds: int, expert: bool):
  """(dataset, seed) pairs of the sweep."""
  return [('mixed', s) for s in range(seeds)] + ([('expert', 0)] if expert else [])


def _load(path):
  with open(path) as f:
    return json.load(f)


def _dump(obj, path):
  with open(path + '.tmp', 'w') as f:
    json.dump(obj, f, indent=2)
  os.replace(path + '.tmp', path)


def train_variant(base, name, dataset, seed, root, episodes) -> dict:
  """Trains (or resumes, or reuses) one variant; returns its report.json."""
  from ld_mpc_jax.runs.train import train_and_evaluate
  workdir = os.path.join(root, dataset, name, f'seed{seed}')
  report_path = os.path.join(workdir, 'report.json')
  if os.path.exists(report_path):
    return _load(report_path)
  # Baselines are evaluated once, on the full model's checkpoints, by the sweep itself.
  config = with_overrides(base, {**VARIANTS[name][1], 'seed': seed, 'data.preset': dataset,
                                 'eval.episodes': episodes, 'eval.baselines': ()})
  return train_and_evaluate(config, workdir)


def evaluate_on(root, source, dataset, seed, tag, overrides, mode, episodes, noise=0.0) -> dict:
  """Evaluates `mode` on `source`'s checkpoint with overrides; cached as <tag>.json beside it."""
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.eval.spec import EvalSpec
  from ld_mpc_jax.runs.loop import run_evaluation
  workdir = os.path.join(root, dataset, source, f'seed{seed}')
  path = os.path.join(workdir, f'{tag}.json')
  if os.path.exists(path):
    return _load(path)
  config, params, _ = run_checks.load_for_evaluation(workdir)
  config = with_overrides(config, overrides)
  # The episodes of the variants' own final evaluation (its first evaluation seed, not the
  # training seed), so that every policy of a training seed runs the same episodes.
  eval_seed = config.eval.seeds[0]
  r = run_evaluation(EvalSpec.from_config(config), params, mode, episodes, eval_seed,
                     obs_noise_std=noise)
  out = {k: v for k, v in r.items() if k != 'successes'}
  out['eval_seed'] = eval_seed
  out['num_params'] = _load(os.path.join(workdir, 'report.json'))['num_params']
  _dump(out, path)
  return out


SAME_EPISODE = ('split', 'eval_seed', 'episode', 'reset_seed', 'goal_id')


def episode_records(root, name, dataset, seed) -> list:
  """Per-episode held-out records of one policy at one training seed: a trained variant's own
  final evaluation (episodes.csv), else the `eval_<name>.json` the sweep wrote."""
  source = VARIANTS[name][2] if name in VARIANTS else 'ldmpc'
  workdir = os.path.join(root, dataset, source or name, f'seed{seed}')
  path = os.path.join(workdir, 'episodes.csv' if source is None else f'eval_{name}.json')
  if not os.path.exists(path):
    return []
  return stats.select(read_records(path), policy='plan' if source is None else None,
                      split='held_out')


def paired_with(root, reference, other, pairs) -> dict:
  """Exact McNemar of `reference` against `other` on the episodes both ran, pooled over the
  `mixed` training seeds of `pairs`; None unless both ran exactly the same episodes."""
  key = lambda r: tuple(str(r[k]) for k in SAME_EPISODE)
  a, b = [], []
  for dataset, seed in pairs:
    if dataset != 'mixed':
      continue
    ref, oth = (episode_records(root, n, dataset, seed) for n in (reference, other))
    if not ref or [key(r) for r in ref] != [key(r) for r in oth]:
      return None  # Different episodes (e.g. files of the older sweep): no paired test.
    a += [int(r['success']) for r in ref]
    b += [int(r['success']) for r in oth]
  return stats.mcnemar_exact(a, b) if a else None


def paired_md(root, rows, pairs, labels, reference='ldmpc') -> str:
  """Markdown table: `reference` against every other row on the same episodes."""
  lines = [f'{labels[reference]} against each policy on the same held-out episodes, pooled '
           'over the `mixed` training seeds (exact McNemar):', '',
           '| policy | only the reference succeeded | only this policy succeeded | p |',
           '|---|---|---|---|']
  for name in rows:
    if name == reference:
      continue
    t = paired_with(root, reference, name, pairs)
    cells = ('-', '-', 'not run on the same episodes') if t is None else (
        t['a_only'], t['b_only'], f"{t['p_value']:.2g}")
    lines.append(f'| {labels[name]} | ' + ' | '.join(map(str, cells)) + ' |')
  return '\n'.join(lines) + '\n'


def row(label, results) -> dict:
  """Table row from per-run results {(dataset, seed): result}."""
  mixed = [r for (ds, _), r in sorted(results.items()) if ds == 'mixed']
  expert = [r for (ds, _), r in results.items() if ds == 'expert']
  succ = [r['success_rate'] for r in mixed]
  return {
      'label': label,
      'mixed_success_per_seed': succ,
      'mixed_success_mean': float(np.mean(succ)) if succ else None,
      'mixed_success_ci95': seed_interval(succ) if succ else None,
      'mixed_return_mean': float(np.mean([r['mean_return'] for r in mixed])) if mixed else None,
      'expert_success': expert[0]['success_rate'] if expert else None,
      'expert_success_ci95': expert[0]['success_ci95'] if expert else None,
      'decisions_per_s': float(np.median([r['decisions_per_s'] for r in mixed + expert])),
      'num_params': (mixed + expert)[0]['num_params'],
  }


def _fmt(x, pattern='{:.2f}'):
  return '-' if x is None else pattern.format(x)


def table_md(rows: dict, wall_s: float, seeds: int, command: str) -> str:
  lines = [f'Command: `{command}`; wall time {wall_s / 60:.0f} min (this and earlier '
           f'invocations of the sweep). Success over {seeds} training seeds on `mixed` (mean, '
           '95% t-interval over seeds, per-seed values) and one seed on `expert` (95% Wilson '
           'interval over episodes); return is the mean over the mixed seeds.', '',
           '| variant | mixed success | per seed | mixed return | expert success | '
           'decisions/s | params |', '|---|---|---|---|---|---|---|']
  for r in rows.values():
    ci = r['mixed_success_ci95']
    exp_ci = r['expert_success_ci95']
    lines.append(
        f"| {r['label']} | {_fmt(r['mixed_success_mean'])}"
        f"{'' if ci is None else f' [{ci[0]:.2f}, {ci[1]:.2f}]'} | "
        f"{', '.join(f'{s:.2f}' for s in r['mixed_success_per_seed'])} | "
        f"{_fmt(r['mixed_return_mean'], '{:.0f}')} | {_fmt(r['expert_success'])}"
        f"{'' if exp_ci is None else f' [{exp_ci[0]:.2f}, {exp_ci[1]:.2f}]'} | "
        f"{r['decisions_per_s']:.0f} | {r['num_params']:,} |")
  return '\n'.join(lines) + '\n'


def bar_plot(rows: dict, path: str) -> None:
  import matplotlib
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt
  names = [n for n, r in rows.items() if r['mixed_success_mean'] is not None]
  means = np.array([rows[n]['mixed_success_mean'] for n in names])
  ci = np.array([rows[n]['mixed_success_ci95'] for n in names])
  fig, ax = plt.subplots(figsize=(9, 4))
  x = np.arange(len(names))
  ax.bar(x, means, yerr=np.abs(ci.T - means), capsize=4, color='tab:blue', label='mixed')
  expert = [rows[n]['expert_success'] for n in names]
  if any(e is not None for e in expert):
    ax.scatter(x, [np.nan if e is None else e for e in expert], color='tab:orange',
               zorder=3, label='expert (1 seed)')
  ax.set_xticks(x, [rows[n]['label'] for n in names], rotation=30, ha='right', fontsize=8)
  ax.set_ylabel('door-open-v3 success')
  ax.set_ylim(0, 1.05)
  ax.legend(loc='upper left', bbox_to_anchor=(1.0, 1.0))
  fig.tight_layout()
  fig.savefig(path, dpi=120)
  plt.close(fig)


def _clock(root: str):
  """Seconds of this sweep so far, over resumes (its clock file in `root`)."""
  os.makedirs(root, exist_ok=True)
  clock_path = os.path.join(root, 'wall_seconds.json')
  prior_wall = _load(clock_path)['seconds'] if os.path.exists(clock_path) else 0.0
  start = time.perf_counter()
  return lambda: prior_wall + time.perf_counter() - start


def _check_flags() -> None:
  """Bad flags: one line, exit code 2."""
  with cli.one_line_errors():
    cli.check_subset('variants', _VARIANTS.value, VARIANTS)
    if _SEEDS.value < 1 or _EPISODES.value < 1:
      raise ValueError(f'--seeds and --episodes must be >= 1, got {_SEEDS.value}, '
                       f'{_EPISODES.value}')


def _labels() -> dict:
  """name -> label of every variant and baseline."""
  return {**{n: v[0] for n, v in VARIANTS.items()}, **{n: v[0] for n, v in BASELINES.items()}}


def _noise_sweep(root, rows, noise_stds, episodes, log) -> dict:
  """{policy: {std: success}} of LD-MPC and the two best baselines (mixed data, seed 0)."""
  baselines = sorted(BASELINES, key=lambda n: -(rows[n]['mixed_success_mean'] or 0))[:2]
  modes = {'ldmpc': 'plan', **{n: BASELINES[n][1] for n in baselines}}
  sweep = {}
  for name, mode in modes.items():
    sweep[name] = {'0.0': rows[name]['mixed_success_per_seed'][0]}
    for std in [s for s in noise_stds if s > 0]:
      log(f'noise sweep {name}, obs noise std {std}')
      r = evaluate_on(root, 'ldmpc', 'mixed', 0, f'noise_{name}_{std}', {}, mode, episodes,
                      noise=std)
      sweep[name][str(std)] = r['success_rate']
  return sweep


def _noise_md(sweep: dict, labels: dict) -> str:
  """The noise sweep's markdown table."""
  stds = list(next(iter(sweep.values())))
  md = ('\nObservation-noise sweep (mixed, seed 0; success vs. Gaussian noise std on the '
        'observation):\n\n| policy | ' + ' | '.join(stds) + ' |\n|---|' + '---|' * len(stds) + '\n')
  for name, by_std in sweep.items():
    md += f'| {labels[name]} | ' + ' | '.join(f'{by_std[s]:.2f}' for s in stds) + ' |\n'
  return md


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  root, episodes = _WORKDIR.value, _EPISODES.value
  _check_flags()
  base = _CONFIG.value
  wall = _clock(root)
  clock_path = os.path.join(root, 'wall_seconds.json')
  pairs = runs(_SEEDS.value, _EXPERT.value)
  results = {}  # name -> {(dataset, seed): result}

  def log(msg):
    print(f'[ablations {wall() / 60:6.1f} min] {msg}', flush=True)
    _dump({'seconds': wall()}, clock_path)

  order = [n for n in VARIANTS if n in _VARIANTS.value and VARIANTS[n][2] is None]
  if 'ldmpc' not in order:
    order.append('ldmpc')  # The baselines and variant 6 run on its checkpoints.
  for name in order:
    for dataset, seed in pairs:
      log(f'train {name} on {dataset}, seed {seed}')
      results.setdefault(name, {})[(dataset, seed)] = train_variant(
          base, name, dataset, seed, root, episodes)
  for name in _VARIANTS.value:
    label, overrides, source = VARIANTS[name]
    if source is None:
      continue
    for dataset, seed in pairs:
      log(f'evaluate {name} on {dataset}, seed {seed}')
      results.setdefault(name, {})[(dataset, seed)] = evaluate_on(
          root, source, dataset, seed, f'eval_{name}', overrides, 'plan', episodes)
  for name, (label, mode) in BASELINES.items():
    for dataset, seed in pairs:
      log(f'baseline {name} on {dataset}, seed {seed}')
      results.setdefault(name, {})[(dataset, seed)] = evaluate_on(
          root, 'ldmpc', dataset, seed, f'eval_{name}', {}, mode, episodes)

  labels = _labels()
  rows = {n: row(labels[n], results[n]) for n in list(VARIANTS) + list(BASELINES)
          if n in results}
  command = 'python -m experiments.train ablations ' + ' '.join(sys.argv[1:])
  out = {'rows': rows, 'wall_seconds': wall(), 'command': command.strip(),
         'episodes': episodes, 'seeds': _SEEDS.value}

  if _NOISE.value:
    out['noise_sweep'] = _noise_sweep(root, rows, base.eval.noise_stds, episodes, log)
  out['wall_seconds'] = wall()
  _dump(out, os.path.join(root, 'ablations.json'))
  md = table_md(rows, out['wall_seconds'], _SEEDS.value, out['command'])
  if 'ldmpc' in rows:
    md += '\n' + paired_md(root, rows, pairs, labels)
  if 'noise_sweep' in out:
    md += _noise_md(out['noise_sweep'], labels)
  with open(os.path.join(root, 'ablations.md'), 'w') as f:
    f.write(md)
  bar_plot(rows, os.path.join(root, 'ablations.png'))
  log(f'wrote {root}/ablations.md, ablations.json, ablations.png')
  print(md)
