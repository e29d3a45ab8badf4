r"""Evaluation speed: episodes one at a time against environments in lockstep, in the same run.

  python -m experiments.benchmark_planning evaluation --workdir=runs/sweep/door_open_cpu/seed0 \
      --modes=plan,actor,proposal --episodes=50 --repeats=3 \
      --out=runs/benchmark/benchmark_evaluation.json

For each policy mode, runs the same held-out episodes (evaluation seed 0) of a trained checkpoint
(a) one at a time, one jitted call per decision (`agent.make_policy`), and (b) in lockstep,
`--batch_size` environments with one jitted call per decision for all of them
(`agent.BatchAgentPolicy`; the planner maps `--plan_chunk` environments per vmap, or with 0 calls
the single-environment planner once per environment). Times are wall
clock of the whole evaluation loop, environment included, compilation excluded (both warm up
first); medians over --repeats. Also reports whether both ways gave the same per-episode
outcomes. Writes a JSON list and a markdown table beside it.
"""

import json
import os

from absl import app, flags, logging
import numpy as np

from ld_mpc_jax.cli import errors as cli

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training run directory (a checkpoint).')
_MODES = flags.DEFINE_list('modes', ['plan', 'actor', 'proposal'], 'Policy modes.')
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Episodes per evaluation.')
_BATCH = flags.DEFINE_integer('batch_size', 50, 'Environments in lockstep.')
_CHUNK = flags.DEFINE_integer('plan_chunk', None, 'Planner environments per vmap '
                              '(0: one call per environment; default: config.eval.plan_chunk).')
_REPEATS = flags.DEFINE_integer('repeats', 1, 'Repeated measurements (median reported).')
_OUT = flags.DEFINE_string('out', 'runs/benchmark/benchmark_evaluation.json', 'JSON output.')
flags.mark_flag_as_required('workdir')


def _table(meta: dict, rows: list, num_episodes: int) -> list:
  """The markdown lines of the measurement."""
  lines = [f"Device: {meta['device']}, {meta['cpu_count']} cores; 1-min load average at start "
           f"{meta['load_average_at_start']:.2f}; checkpoint {meta['workdir']} step {meta['step']}; "
           f"{num_episodes} held-out episodes; medians over {meta['repeats']} run(s).", '',
           '| policy | decisions | one at a time s | lockstep s (N envs) | speed-up | '
           'same outcomes |', '| --- | ---: | ---: | ---: | ---: | ---: |']
  for r in rows:
    lines.append(f"| {r['mode']} | {r['decisions']} | {r['one_at_a_time_s']['median']:.1f} | "
                 f"{r['lockstep_s']['median']:.1f} ({r['batch_size']}) | {r['speedup']:.2f}x | "
                 f"{r['same_outcomes']:.0%} |")
  return lines


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  import jax
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.eval import evaluation, evaluation_suite
  from ld_mpc_jax.eval.spec import EvalSpec
  from ld_mpc_jax.plan.agent import BatchAgentPolicy, make_policy
  with cli.one_line_errors():
    config, params, step = run_checks.load_for_evaluation(_WORKDIR.value)
    spec = EvalSpec.from_config(config)
  e = spec.eval
  chunk = e.plan_chunk if _CHUNK.value is None else _CHUNK.value
  episodes = evaluation_suite.episodes(spec.goals, 'held_out', 0, _EPISODES.value)
  kwargs = dict(action_repeat=e.action_repeat, max_episode_steps=e.max_episode_steps,
                progress=False)
  load = os.getloadavg()[0]
  rows = []
  for mode in _MODES.value:
    single_s, batch_s = [], []
    for _ in range(_REPEATS.value):
      policy, reset = make_policy(spec.act, params, mode, seed=0)
      single, info1 = evaluation.run_episodes(evaluation.CallablePolicy(policy, reset), episodes,
                                              spec.task, batch_size=1, **kwargs)
      single_s.append(info1['seconds'])
      batch_policy = BatchAgentPolicy(spec.act, params, mode, seed=0,
                                      chunk=chunk if mode in ('plan', 'mppi') else None)
      batched, info2 = evaluation.run_episodes(batch_policy, episodes, spec.task,
                                               batch_size=_BATCH.value, **kwargs)
      batch_s.append(info2['seconds'])
    same = float(np.mean([a['success'] == b['success'] and a['length'] == b['length']
                          for a, b in zip(single, batched)]))
    row = dict(mode=mode, episodes=len(episodes), batch_size=_BATCH.value,
               plan_chunk=chunk if mode in ('plan', 'mppi') else None,
               decisions=info1['decisions'],
               one_at_a_time_s=dict(median=float(np.median(single_s)), min=min(single_s),
                                    max=max(single_s)),
               lockstep_s=dict(median=float(np.median(batch_s)), min=min(batch_s),
                               max=max(batch_s)),
               speedup=float(np.median(single_s) / np.median(batch_s)),
               same_outcomes=same,
               success_one_at_a_time=float(np.mean([r['success'] for r in single])),
               success_lockstep=float(np.mean([r['success'] for r in batched])))
    rows.append(row)
    print(f"{mode}: one at a time {row['one_at_a_time_s']['median']:.1f} s, lockstep "
          f"{row['lockstep_s']['median']:.1f} s -> {row['speedup']:.2f}x "
          f"({row['decisions']} decisions; same outcomes in {same:.0%} of episodes)")
  meta = dict(workdir=_WORKDIR.value, step=step, device=str(jax.devices()[0].device_kind),
              cpu_count=os.cpu_count(), load_average_at_start=load, repeats=_REPEATS.value)
  os.makedirs(os.path.dirname(os.path.abspath(_OUT.value)), exist_ok=True)
  with open(_OUT.value, 'w') as f:
    json.dump([{**meta, **r} for r in rows], f, indent=1)
  lines = _table(meta, rows, len(episodes))
  with open(os.path.splitext(_OUT.value)[0] + '.md', 'w') as f:
    f.write('\n'.join(lines) + '\n')
  print('\n'.join(lines))
