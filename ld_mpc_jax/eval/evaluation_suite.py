"""Evaluating a checkpoint: policies x goal splits x evaluation seeds, with paired statistics.

`evaluate_policy` runs one policy mode on one split and seed with the batched evaluation and
returns its per-episode records; `evaluate_checkpoint` runs a grid of them, caching each cell as
JSON under `<workdir>/evals/` (a crash or a re-run loses nothing already evaluated), and
`summarize` pools the records (per split and policy: Wilson interval, spread over runs) and
pairs policies on the same episodes (exact McNemar test). `markdown` renders that as tables.
"""

import functools
import hashlib
import itertools
import json
import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import jax
import numpy as np

from ld_mpc_jax import data, envs
from ld_mpc_jax.eval import evaluation
from ld_mpc_jax.ops import sharding, stats
from ld_mpc_jax.plan.agent import BatchAgentPolicy
from ld_mpc_jax.model.models import informative_dims
from ld_mpc_jax.eval.anchors import (  # noqa: F401 (re-exported: the suite's comparisons)
    against_anchor, against_anchor_by_task, anchor_markdown, behind_by_anchor_time,
    behind_markdown, by_task_markdown, departure_share)
from ld_mpc_jax.envs import goals
from ld_mpc_jax.envs.pixels import image_env_factory
from ld_mpc_jax.eval.spec import EvalSpec, GoalSource, key_json

POLICY_NAMES = {'plan': 'planner', 'actor': 'actor prior', 'proposal': 'proposal alone',
                'mppi': 'MPPI (learned model)'}


@functools.lru_cache(maxsize=16)
def _dataset_goals(task, preset, episodes, seed, data_dir, action_repeat, max_episode_steps):
  ds = data.get_or_collect(task, preset, episodes, seed, data_dir, action_repeat=action_repeat,
                           max_episode_steps=max_episode_steps)
  scripted = ds.metadata.get('source') == envs.SUITE.scripted_source
  return goals.dataset_goal_vectors(ds), ds.metadata.get('seed') if scripted else None


def dataset_goals(source: GoalSource) -> Tuple[np.ndarray, Optional[int]]:
  """(goal vectors [E, 6] of the training data's episode starts, the data's MT1 seed).

  TD-MPC2 data (config.data.source 'tdmpc2') drew a random goal per episode, not MT1 goals: their
  goal vectors come from the observations as for any data, and the MT1 seed is None. Online
  training from scratch (config.online, no init_from) has no dataset: its episodes start from
  the 50 goals of MT1 seed `data.seed`, which are then the training goals, or with
  `online.train_goals='random'` from a fresh goal each: no goal vectors to keep out of held_out
  (continuous draws) and no train split.
  """
  if source.online == 'random':
    return np.zeros((0, envs.metaworld_env.GOAL_DIM)), None
  d = source.data
  if source.online:
    return goals.mt1_goals(d.task, d.seed)[1], d.seed
  if d.source == 'tdmpc2':
    return goals.dataset_goal_vectors(source.load()), None
  return _dataset_goals(d.task, d.preset, d.episodes, d.seed, d.dir, d.action_repeat,
                        d.max_episode_steps)


def available_splits(source: GoalSource, splits: Sequence[str]) -> Tuple[str, ...]:
  """`splits` less 'train' when the data were not collected on MT1 goals (TD-MPC2's data).

  Raises:
    ValueError: nothing left (only the train split was asked for).
  """
  if 'train' not in splits or dataset_goals(source)[1] is not None:
    return tuple(splits)
  kept = tuple(s for s in splits if s != 'train')
  if not kept:
    raise ValueError('the train goal split needs data collected on MT1 goals '
                     f'(config.data.source={data.sources.SCRIPTED}); evaluate on held_out')
  return kept


def episodes(source: GoalSource, split: str, seed: int,
             num_episodes: int) -> List[goals.Episode]:
  """The episodes of one goal split and evaluation seed for the source's task and data."""
  vectors, mt1_seed = dataset_goals(source)
  return goals.make_episodes(source.task, split, seed, num_episodes, vectors, mt1_seed)


def evaluate_policy(spec: EvalSpec, params, mode: str, num_episodes: int,
                    seed: int, split: str = 'held_out', obs_noise_std: Optional[float] = None,
                    video_path: Optional[str] = None, batch_size: Optional[int] = None,
                    progress: bool = False, only: Optional[Sequence[int]] = None,
                    env_factory: Optional[Callable[..., Any]] = None) -> Dict[str, Any]:
  """`mode` ('plan', 'actor', 'proposal', 'mppi') on `num_episodes` episodes of one split
  (`only`: those indices of them; `env_factory` replaces `envs.make_env`).

  Environments run in lockstep, `config.eval.batch_size` at a time (one jitted call per
  decision for all of them; the planner maps `config.eval.plan_chunk` environments per vmap;
  with `config.eval.data_parallel` they are split over all devices).
  `obs_noise_std` (None: `config.eval.obs_noise`): Gaussian noise on the observations, on the
  dimensions `config.eval.obs_noise_dims` says (`noise_stds`).
  Returns `evaluation.result`: summary, `records` (one per episode) and timing.
  """
  e = spec.eval
  batch = batch_size or (1 if video_path else e.batch_size)
  chunk = e.plan_chunk if mode in ('plan', 'mppi') else None
  # This process's devices: with several processes, each runs its own evaluation.
  mesh = sharding.make_mesh(jax.local_devices()) if e.data_parallel else None
  key_seed = seed if e.key_seed < 0 else e.key_seed  # The episodes keep `seed`.
  policy = BatchAgentPolicy(spec.act, params, mode, seed=key_seed, chunk=chunk, mesh=mesh)
  policy.action_noise = float(e.action_noise)  # 0: exactly the policy's action.
  m = spec.act.model
  if env_factory is None and m.images:  # The policy observes rendered frames.
    env_factory = image_env_factory(m.image_size, m.image_channels // 3, proprio=m.proprio)
  eps = episodes(spec.goals, split, seed, num_episodes)
  if only is not None:
    eps = [eps[i] for i in only]
  records, info = evaluation.run_episodes(
      policy, eps, spec.task, batch_size=batch, action_repeat=e.action_repeat,
      max_episode_steps=e.max_episode_steps,
      obs_noise_std=noise_stds(spec, params, obs_noise_std),
      env_factory=env_factory, video_path=video_path, video_episodes=len(eps),
      progress=progress, desc=f'{mode} {split} seed {seed}')
  for r in records:
    r['policy'] = mode
  return evaluation.result(records, info)


def noise_stds(spec: EvalSpec, params, std: Optional[float]):
  """The observation noise of an evaluation: `std` (None: `config.eval.obs_noise`) on every
  dimension, or with `eval.obs_noise_dims = 'informative'` a per-dimension std [obs_dim], 0 on
  the dimensions constant in the training data (models.informative_dims)."""
  std = float(spec.eval.obs_noise if std is None else std)
  if std > 0 and spec.act.model.images:
    raise ValueError('observation noise is noise on the state, and image observations are '
                     'rendered without it: no noise sweep for a model of images')
  if spec.eval.obs_noise_dims == 'all' or std == 0:
    return std
  mask = informative_dims(params)
  if mask is None:
    raise ValueError("config.eval.obs_noise_dims='informative' needs an encoder with observation "
                     'normalisation (config.model.normalize_obs): it tells which dimensions vary')
  return std * mask.astype(np.float64)


# Part of every cache key: raise it when a code change alters the episodes of an unchanged
# config, so that cached cells made by the old code are not reused (2: the softmax safe gate;
# 3: fields at their legacy defaults left out of the key).
CACHE_VERSION = 3


def _cache_key(spec: EvalSpec, step: int, mode: str, split: str, seed: int, num_episodes: int,
               obs_noise_std: float, version: int) -> str:
  """Digest of everything that changes one evaluation's episodes.

  From version 3, `plan` and `data` fields at their legacy defaults (checkpointing: the value a
  config saved before the field existed is read with) are left out: a new field at its no-change
  default leaves every key, and so every cached cell, as it was (spec.CacheKey).
  """
  e = spec.eval
  relevant = dict(version=version, step=step, mode=mode, split=split, seed=seed,
                  episodes=num_episodes, noise=obs_noise_std, **spec.key.sections(version),
                  eval=dict(action_repeat=e.action_repeat, max_episode_steps=e.max_episode_steps))
  if e.key_seed >= 0:  # At its default (-1) it leaves every key as it was.
    relevant['eval']['key_seed'] = e.key_seed
  if e.action_noise > 0:  # Likewise at its default (0).
    relevant['eval']['action_noise'] = float(e.action_noise)
  if obs_noise_std > 0 and e.obs_noise_dims != 'all':  # Likewise.
    relevant['eval']['obs_noise_dims'] = e.obs_noise_dims
  return hashlib.sha1(key_json(relevant).encode()).hexdigest()[:10]


def _cell_paths(workdir: str, spec: EvalSpec, step: int, mode: str, split: str, seed: int,
                num_episodes: int, obs_noise_std: float) -> Tuple[str, str]:
  """(the cache file of one evaluation, the file version 2 named it or None): at version 3 an
  unchanged config still finds the cells cached by version 2 (the same episodes); a later
  version, raised for a change of the episodes, must not."""
  name = lambda v: os.path.join(workdir, 'evals', f'{mode}_{split}_seed{seed}_' + _cache_key(
      spec, step, mode, split, seed, num_episodes, obs_noise_std, v) + '.json')
  return name(CACHE_VERSION), (name(2) if CACHE_VERSION == 3 else None)


def evaluate_checkpoint(spec: EvalSpec, params, workdir: Optional[str],
                        step: int, modes: Sequence[str], splits: Sequence[str],
                        seeds: Sequence[int], num_episodes: int, run: Any = None,
                        obs_noise_std: Optional[float] = None, log=print,
                        progress: bool = True) -> List[dict]:
  """Every (split, seed, mode) evaluation; returns all per-episode records.

  Records carry `run` (e.g. the training seed) so that runs pool and pair correctly, and
  `obs_noise` (None: `config.eval.obs_noise`). Each cell is cached under <workdir>/evals/ and
  reused when its inputs are unchanged.
  """
  obs_noise_std = float(spec.eval.obs_noise if obs_noise_std is None else obs_noise_std)
  records = []
  for split, seed, mode in itertools.product(splits, seeds, modes):
    path, old = (_cell_paths(workdir, spec, step, mode, split, seed, num_episodes,
                             obs_noise_std) if workdir else (None, None))
    found = next((p for p in (path, old) if p and os.path.exists(p)), None)
    if found:
      with open(found) as f:
        cell = json.load(f)
    else:
      r = evaluate_policy(spec, params, mode, num_episodes, seed, split, obs_noise_std,
                          progress=progress)
      cell = dict(summary={k: v for k, v in r.items() if k not in ('records', 'outcomes')},
                  records=r['records'])
      if path:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path + '.tmp', 'w') as f:
          json.dump(cell, f)
        os.replace(path + '.tmp', path)
    s = cell['summary']
    of_run = '' if run is None else f' (run {run})'  # The training seed, in a run of several.
    log(f"{POLICY_NAMES.get(mode, mode)}, {split} goals, evaluation seed {seed}{of_run}: success "
        f"{s['success_rate']:.2f} [{s['success_ci95'][0]:.2f}, {s['success_ci95'][1]:.2f}] "
        + (f'(kept in {found})' if found else f"({s['decisions_per_s']:.0f} decisions/s)"))
    for rec in cell['records']:
      rec['run'] = run
      if obs_noise_std > 0:  # Records of the protocol keep their fields.
        rec['obs_noise'] = obs_noise_std
      rec['decisions_per_s'] = cell['summary']['decisions_per_s']
    records.extend(cell['records'])
  return records


def summarize(records: Sequence[dict]) -> Dict[str, Any]:
  """Pooled per (split, policy) summaries, spread over runs, and paired tests vs. the planner.

  Returns {split: {'policies': {mode: summary}, 'paired': {'plan vs mode': mcnemar}}}, splits
  and policies in the order first seen.
  """
  out: Dict[str, Any] = {}
  splits = list(dict.fromkeys(r['split'] for r in records))
  for split in splits:
    recs = stats.select(records, split=split)
    modes = list(dict.fromkeys(r['policy'] for r in recs))
    policies = {}
    for mode in modes:
      mine = stats.select(recs, policy=mode)
      s = stats.summarize(mine)
      s['per_run'] = stats.spread(mine, 'run')
      s['per_eval_seed'] = stats.spread(mine, 'eval_seed')['rates']
      if all('departures' in r for r in mine):  # Decisions that left the actor prior's plan.
        s['departure_share'] = departure_share(mine)
      s['decisions_per_s'] = float(np.median([r['decisions_per_s'] for r in mine
                                              if 'decisions_per_s' in r] or [np.nan]))
      policies[mode] = s
    paired = {}
    for a, b in itertools.combinations(modes, 2):
      ra, rb = stats.select(recs, policy=a), stats.select(recs, policy=b)
      if {stats.episode_key(r) for r in ra} & {stats.episode_key(r) for r in rb}:
        paired[f'{a} vs {b}'] = stats.paired(ra, rb)
      # else: never on the same episodes (pooled from different files), so no paired test.
    out[split] = dict(policies=policies, paired=paired)
  return out


def markdown(summary: Dict[str, Any]) -> str:
  """Tables of `summarize`'s output: one row per split and policy, then the paired tests."""
  # Episodes end at their first success, so a return does not compare across policies whose
  # success differs: a solved episode's return is short.
  lines = ['| goals | policy | success | 95% CI (Wilson) | per run | mean return (an episode '
           'stops at its success) | decisions/s |', '| --- | --- | --- | --- | --- | --- | --- |']
  for split, s in summary.items():
    for mode, p in s['policies'].items():
      lo, hi = p['success_ci95']
      runs = ', '.join(f'{v:.2f}' for v in p['per_run']['rates'].values())
      speed = p['decisions_per_s']
      speed = 'not recorded' if np.isnan(speed) else f'{speed:.1f}'
      lines.append(f"| {split} | {POLICY_NAMES.get(mode, mode)} | {p['successes']}/"
                   f"{p['episodes']} = {p['success_rate']:.2f} | [{lo:.2f}, {hi:.2f}] | {runs} | "
                   f"{p.get('mean_return', float('nan')):.1f} | {speed} |")
  lines += ['', '| goals | comparison | episodes | only the first succeeded | only the second '
            '| McNemar exact p |', '| --- | --- | --- | --- | --- | --- |']
  for split, s in summary.items():
    for name, t in s['paired'].items():
      a, b = name.split(' vs ')
      lines.append(f"| {split} | {POLICY_NAMES.get(a, a)} vs {POLICY_NAMES.get(b, b)} | {t['n']} "
                   f"| {t['a_only']} | {t['b_only']} | {t['p_value']:.3g} |")
  return '\n'.join(lines) + '\n'
