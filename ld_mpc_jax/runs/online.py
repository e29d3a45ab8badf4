"""Online and offline-to-online training: the planner acts, its episodes feed the replay buffer.

`train_online(plans, workdir)` is the main job's online mode (`config.online.enabled`;
ld_mpc_jax/configs/door_open_online.py). N = `online.num_envs` environments run one episode each
in lockstep (a wave); episodes run their full `online.episode_steps` environment steps, as the
scripted data do, and start from the goals of MT1 seed `config.data.seed` (or, with
`online.train_goals='random'`, from a fresh goal configuration each). From scratch, the
waves of the first `online.seed_steps` environment steps act with uniform random actions; after
them the agent acts with its planner and EMA parameters (one jitted plan per environment, or
`online.plan_chunk` environments per vmap, `agent.BatchAgentPolicy`), with the exploration noise
`online.action_noise_std` / `online.prior_noise_std` on its candidates
(`OnlineSettings.acting_plan`), which evaluation never uses. Updates interleave with acting: once
learning has started, after every decision updates run until floor(`online.update_ratio` x environment steps) have been made, so
from scratch the seed steps' share comes at once (TD-MPC2 pretrains on its seed data likewise).
With `online.demos` = N (ld_mpc_jax.data.demos), N successful scripted episodes on training
goals (or a dataset file's) sit in their own buffer; every batch draws an annealed share of its
windows from them (the actor prior also clones them with `loss.w_demo_bc` > 0),
`online.demo_pretrain_updates` updates on them alone come before the first wave, and no wave
acts at random: the planner acts from the first (or the actor prior in the seed waves, with
`online.demo_seed_actor`), plus the executed-action noise; updates interleave from the first.
With `online.init_from` (an offline run's workdir), the agent starts from that run's latest
checkpoint (parameters, optimiser state, EMA) and samples from that run's dataset and its own
episodes alike.

Checkpoints come at wave ends, every `online.checkpoint_every` environment steps, under the
orbax step = environment steps: the TrainState, and before it `online/buffer_<step>.npz` (the
online episodes in the dataset file format, written atomically, with the counters and the
sampler's RNG state in its metadata). Every other random draw is a function of `config.seed` and
those counters, so a resumed run continues exactly as the uninterrupted one.
"""

import json
import os
import sys
from typing import Any, Dict, Optional, Sequence

import jax
import ml_collections

from ld_mpc_jax import data
from ld_mpc_jax.data.demos import sparse_dataset
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import LearnSettings
from ld_mpc_jax.online.job import OnlineJob
from ld_mpc_jax.runs import loop as runs, online_report
from ld_mpc_jax.runs.progress import progress_bar
from ld_mpc_jax.runs.seed_plan import SeedPlan, seed_source


def check_init_from(plans: Sequence[SeedPlan]) -> Optional[ml_collections.ConfigDict]:
  """The config of the offline run `online.init_from` of the training seeds' `plans`
  (runs.seed_plan.seed_plans; None: from scratch).

  A run of several offline seeds (`train.num_seeds`: a folder per seed) gives each training seed
  its own: seed s fine-tunes from <init_from>/seed<s> (`seed_plan.seed_source`); every one is
  checked, and they must share their data. Raises a one-line ValueError when one is not a
  training workdir with a checkpoint, when it was trained on another task, or when its networks
  differ from the plan's (the parameters would not fit).
  """
  if not plans[0].online.init_from:
    return None
  sources = [_check_source(p) for p in plans]
  for p, source in zip(plans[1:], sources[1:]):
    if source.data.to_dict() != sources[0].data.to_dict():
      raise ValueError(f'config.online.init_from: {p.online.init_from!r} was trained on other '
                       f'data than {plans[0].online.init_from!r}')
  return sources[0]


def _check_source(plan: SeedPlan) -> ml_collections.ConfigDict:
  path = seed_source(plan.online.init_from, plan.seed)
  try:
    source = checkpointing.load_config(path)
  except FileNotFoundError as err:
    if os.path.isdir(path) and any(n.startswith('seed') for n in os.listdir(path)):
      raise ValueError(f'config.online.init_from={path!r} is a run of several seeds without '
                       f'seed{plan.seed}/, which training seed {plan.seed} starts from') from None
    raise ValueError(f'config.online.init_from: {err}') from None
  if source.task != plan.task:  # Its dataset would be collected again on the wrong task.
    raise ValueError(f'config.online.init_from={path!r} was trained on {source.task}, not '
                     f'{plan.task}: pass --config.task={source.task}')
  if checkpointing.checkpoint_manager(path).latest_step() is None:
    raise ValueError(f'config.online.init_from={path!r} has no checkpoint')
  shapes = lambda learn: jax.tree_util.tree_map(
      lambda x: x.shape, checkpointing.abstract_state(learn))
  if shapes(LearnSettings.from_config(source)) != shapes(plan.learn):
    model = plan.fields()['model']
    fields = [f'model.{k}' for k in sorted(model) if k != 'dropout' and  # JSON: lists = tuples.
              json.dumps(source.model[k] if k in source.model else None)
              != json.dumps(model[k])]
    raise ValueError(f'config.online.init_from={path!r} has other networks than this config '
                     f'(differs in {", ".join(fields) or "critic/horizon"})')
  return source


def train_online(plans: Sequence[SeedPlan], workdir: str) -> Dict[str, Any]:
  """Online (or offline-to-online) training and evaluation of the training seeds' `plans`
  (runs.seed_plan.seed_plans of the run in `workdir`); returns the report.

  `train.train_and_evaluate`, the entry, has checked the config, `online.init_from`
  (`check_init_from`, whose data the plans then hold) and each seed's workdir. Resumes from the
  latest checkpoint in <workdir>/checkpoints. Writes config.json, online.csv (one row per wave:
  environment steps, updates, training episodes' return and success), losses.csv (the wave's
  last update's losses), eval.csv (held-out success every `online.eval_every` environment
  steps), tb/, online.png, episodes.csv, report.json and report.md, like the offline job. With
  `train.num_seeds` = N > 1 each seed writes these in <workdir>/seed<seed>, and the run adds
  pooled.json and pooled.md (online_report.write_pooled); the returned report is then the
  pooled one, with each seed's report under 'seeds'.
  """
  first = plans[0]  # The seeds' plans differ in their seeds (and sources) only.
  fine_tune = bool(first.online.init_from)
  offline = data.load_dataset(first.data) if fine_tune else None
  if offline is not None:
    runs.check_data_fits(offline, first.learn.model, first.loop.batch_size)
    if first.online.reward == 'sparse':  # Its data with the reward the run records.
      offline = sparse_dataset(offline)
  if not first.online.update_ratio:  # Once, before any work.
    print('warning: config.online.update_ratio=0: no updates; the agent is evaluated as it '
          f"starts ({'the offline run' if fine_tune else 'untrained'})", file=sys.stderr)
  job = online_job(plans, offline)
  o, seed_runs = first.online, runs.SeedRuns([seat.run for seat in job.seats])
  if fine_tune and job.progress == 0:  # Held-out success before fine-tuning.
    seed_runs.periodic_eval(job.eval_params(), 0)
  try:
    runs.loop(seed_runs, job, o.env_steps, o.checkpoint_every, o.eval_every)
  finally:
    job.bar.close()  # Its line ends: an error line (a full disk) starts a line of its own.
  reports, records = [], []
  for seat, params in zip(job.seats, job.eval_params()):
    final, _, summary, recs = seat.run.final_evaluation(params, job.progress)
    report = online_report.report(job, seat, final, summary)
    reports.append(seat.run.write_report(report, online_report.summary_md(report), recs))
    records.append(recs)
  if len(job.seats) == 1:
    return reports[0]
  pooled = online_report.write_pooled(workdir, [s.online.seed for s in job.seats], reports,
                                      records)
  return dict(pooled, seeds=reports)


def online_job(plans: Sequence[SeedPlan], offline: Optional[data.Dataset]) -> OnlineJob:
  """The online job of the training seeds' `plans` (`offline`: the dataset of the run they
  fine-tune, None from scratch), resumed from their checkpoints where they have some."""
  first = plans[0]
  sources = ([seed_source(p.online.init_from, p.seed) for p in plans]
             if first.online.init_from else None)
  bar = lambda initial: progress_bar(first.online.env_steps, initial, 'online', unit='env step')
  return OnlineJob(plans, [runs.Run(p) for p in plans], offline, bar, online_report.log_wave,
                   sources)
