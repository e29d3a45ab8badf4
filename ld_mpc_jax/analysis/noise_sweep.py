"""Success under observation noise: every policy at every noise std on the same held-out
episodes (`config.eval.obs_noise_dims` says which dimensions get it), its table and its plot.

Records are evaluation_suite's, with `obs_noise` (the std) added; records of one std and two
policies pair on the episode (stats.EPISODE_KEY), so each row has its McNemar test against the
planner, and `of_clean` is a policy's success over its own success without noise.
"""

from typing import Any, Dict, List, Optional, Sequence

from ld_mpc_jax.eval import evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.ops import stats

POLICY_NAMES = evaluation_suite.POLICY_NAMES


def run_sweep(spec: EvalSpec, params, workdir: Optional[str], step: int, modes: Sequence[str],
              seeds: Sequence[int], num_episodes: int, stds: Sequence[float], run: Any = None,
              log=print, progress: bool = True) -> List[dict]:
  """The records of every (std, mode, evaluation seed) on held-out goals, each cell cached under
  <workdir>/evals/ like any evaluation (a std of 0 is the protocol's cell)."""
  records = []
  for std in stds:
    for rec in evaluation_suite.evaluate_checkpoint(
        spec, params, workdir, step, modes, ('held_out',), seeds, num_episodes, run=run,
        obs_noise_std=float(std), log=log, progress=progress):
      rec['obs_noise'] = float(std)
      records.append(rec)
  return records


def table(records: Sequence[dict]) -> List[Dict[str, Any]]:
  """One row per (std, policy), stds ascending, policies in the records' order: successes,
  episodes, rate, Wilson interval, `of_clean` (rate over the policy's rate at std 0, when the
  sweep has it) and `vs_plan` (McNemar against the planner at that std; None for the planner)."""
  stds = sorted({float(r['obs_noise']) for r in records})
  modes = list(dict.fromkeys(r['policy'] for r in records))
  rows = []
  for std in stds:
    here = [r for r in records if float(r['obs_noise']) == std]
    for mode in modes:
      mine = stats.select(here, policy=mode)
      if not mine:
        continue
      row = dict(obs_noise=std, policy=mode, **stats.summarize(mine))
      clean = [r for r in records if float(r['obs_noise']) == 0.0 and r['policy'] == mode]
      row['of_clean'] = (row['success_rate'] / stats.summarize(clean)['success_rate']
                         if clean and any(int(r['success']) for r in clean) else None)
      plan = stats.select(here, policy='plan')
      row['vs_plan'] = stats.paired(plan, mine) if plan and mode != 'plan' else None
      rows.append(row)
  return rows


def markdown(rows: Sequence[dict]) -> str:
  """The rows of `table` as a markdown table."""
  lines = ['| obs noise std | policy | success | 95% CI | of clean | planner only / this only, '
           'McNemar p |', '| --- | --- | --- | --- | --- | --- |']
  for r in rows:
    lo, hi = r['success_ci95']
    clean = '' if r['of_clean'] is None else f"{r['of_clean']:.2f}"
    t = r['vs_plan']
    test = '' if t is None else f"{t['a_only']} / {t['b_only']}, p = {t['p_value']:.2g}"
    lines.append(f"| {r['obs_noise']:g} | {POLICY_NAMES.get(r['policy'], r['policy'])} | "
                 f"{r['successes']}/{r['episodes']} = {r['success_rate']:.2f} | "
                 f"[{lo:.2f}, {hi:.2f}] | {clean} | {test} |")
  return '\n'.join(lines) + '\n'


def plot(rows: Sequence[dict], path: str, title: str = '') -> str:
  """Success against the noise std, one line per policy with its Wilson band; writes `path`."""
  import matplotlib  # pylint: disable=g-import-not-at-top
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt  # pylint: disable=g-import-not-at-top
  fig, ax = plt.subplots(figsize=(5, 3.5))
  for mode in dict.fromkeys(r['policy'] for r in rows):
    mine = [r for r in rows if r['policy'] == mode]
    x = [r['obs_noise'] for r in mine]
    ax.plot(x, [r['success_rate'] for r in mine], marker='o',
            label=POLICY_NAMES.get(mode, mode))
    ax.fill_between(x, [r['success_ci95'][0] for r in mine], [r['success_ci95'][1] for r in mine],
                    alpha=0.2)
  ax.set_xlabel('observation noise std')
  ax.set_ylabel('success (held-out goals)')
  ax.set_ylim(0, 1.02)
  ax.set_title(title)
  ax.legend()
  fig.tight_layout()
  fig.savefig(path, dpi=120)
  plt.close(fig)
  return path
