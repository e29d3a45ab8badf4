"""Online and offline-to-online training: the planner acts, its episodes feed the replay buffer.

`train_online(config, workdir)` is the main job's online mode (`config.online.enabled`;
experiments/configs/door_open_online.py). N = `online.num_envs` environments run one episode each
in lockstep (a wave); episodes run their full `online.episode_steps` environment steps, as the
scripted data do, and start from the goals of MT1 seed `config.data.seed` (or, with
`online.train_goals='random'`, from a fresh goal configuration each). From scratch, the
waves of the first `online.seed_steps` environment steps act with uniform random actions; after
them the agent acts with its planner and EMA parameters (one jitted plan per environment, or
`online.plan_chunk` environments per vmap, `agent.BatchAgentPolicy`), with the exploration noise
`online.action_noise_std` / `online.prior_noise_std` on its candidates (`acting_config`), which
evaluation never uses. Updates interleave with acting: once learning has started, after every
decision updates run until floor(`online.update_ratio` x environment steps) have been made, so
from scratch the seed steps' share comes at once (TD-MPC2 pretrains on its seed data likewise).
With `online.demos` = N (ld_mpc_jax.data.demos), N successful scripted episodes on training
goals (or a dataset file's) sit in their own buffer; every batch draws an annealed share of its
windows from them, `online.demo_pretrain_updates` updates on them alone come before the first
wave, and the planner acts from the first wave (no random seed waves).
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
import time
from typing import Any, Dict, List, Optional

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import tqdm

from ld_mpc_jax import checkpointing, data, envs, run_files, runs, sharding
from ld_mpc_jax.agent import BatchAgentPolicy
from ld_mpc_jax.config_checks import validate_config
from ld_mpc_jax.envs import goals
from ld_mpc_jax.exploration import acting_config, ar1_noise, executed_noise
from ld_mpc_jax.models import count_params, set_obs_normalization
from ld_mpc_jax.search import CANDIDATES
from ld_mpc_jax.train_state import create_train_state, make_multi_update, make_update

from ld_mpc_jax.data.demos import demo_share, get_demos
from ld_mpc_jax.data.online_buffer import BUFFER_DIR, Buffer, buffer_path
from ld_mpc_jax.run_files import LOSSES_CSV, ONLINE_CSV



def check_init_from(config: ml_collections.ConfigDict) -> Optional[ml_collections.ConfigDict]:
  """The config of the offline run `online.init_from` (None: from scratch).

  Raises a one-line ValueError when it is not a training workdir with a checkpoint, when it was
  trained on another task, or when its networks differ from config's (the parameters would not
  fit).
  """
  path = config.online.init_from
  if not path:
    return None
  try:
    source = checkpointing.load_config(path)
  except FileNotFoundError as err:
    raise ValueError(f'config.online.init_from: {err}') from None
  if source.task != config.task:  # Its dataset would be collected again on the wrong task.
    raise ValueError(f'config.online.init_from={path!r} was trained on {source.task}, not '
                     f'{config.task}: pass --config.task={source.task}')
  if checkpointing.checkpoint_manager(path).latest_step() is None:
    raise ValueError(f'config.online.init_from={path!r} has no checkpoint')
  shapes = lambda c: jax.tree_util.tree_map(lambda x: x.shape, checkpointing.abstract_state(c))
  if shapes(source) != shapes(config):
    fields = [f'model.{k}' for k in config.model if k != 'dropout' and  # JSON: lists = tuples.
              json.dumps(source.model[k] if k in source.model else None)
              != json.dumps(config.model[k])]
    raise ValueError(f'config.online.init_from={path!r} has other networks than this config '
                     f'(differs in {", ".join(fields) or "critic/horizon"})')
  return source


class OnlineJob:
  """An online run as a `runs.Job`: each advance is one wave of episodes and its updates.

  Holds the TrainState, the buffer, the counters (environment steps: the job's progress) and the
  environments.
  """

  def __init__(self, config, run: runs.Run, source, offline: Optional[data.Dataset]):
    self.config, self.run, self.source, o = config, run, source, config.online
    self.buffer = Buffer(runs.window_length(config), offline, config.seed, get_demos(config))
    self.counters = dict(env_steps=0, updates=0, episodes=0, train_seconds=0.0,
                         pretrain_updates=0)
    # Resume: the newest checkpoint that has its buffer file.
    self.state = run.restore(lambda step: None if os.path.exists(buffer_path(run.workdir, step))
                             else f'no {buffer_path(run.workdir, step)}')
    if self.state is not None:
      self.counters = self.buffer.load(buffer_path(run.workdir, run.step))
    elif source is not None:
      self.state = checkpointing.restore_latest(
          checkpointing.checkpoint_manager(o.init_from), config)
    else:  # From scratch; observation statistics come with the seed data (catch_up).
      self.state = create_train_state(config, jax.random.key(config.seed))
      self.counters['normalized'] = not config.model.normalize_obs
    # Fine-tuning, and runs with demonstrations (MoDem's seeding phase acts with the policy
    # pretrained on them, plus the executed-action noise), act with the planner from the start.
    self.learn_start = 0 if source is not None or o.demos else o.seed_steps
    self.per_call = o.updates_per_call
    self.update = (make_update(config) if self.per_call == 1
                   else make_multi_update(config, self.per_call))
    self.update_key = jax.random.key(config.seed + 1)
    self.act_config = acting_config(config)
    self.envs = [envs.make_env(config.task, seed=config.data.seed,
                               action_repeat=config.eval.action_repeat,
                               max_episode_steps=o.episode_steps,
                               random_goals=o.train_goals == 'random')
                 for _ in range(o.num_envs)]
    self.metrics, self.last, self.noise_std = {}, None, 0.0
    self.bar = tqdm.tqdm(total=o.env_steps, initial=self.counters['env_steps'], desc='online',
                         unit='env step', dynamic_ncols=True)

  @property
  def progress(self) -> int:
    return self.counters['env_steps']

  def learning(self) -> bool:
    return self.counters['env_steps'] >= self.learn_start

  def catch_up(self) -> None:
    """Updates until floor(update_ratio x environment steps) have been made.

    From scratch, the first call sets the encoder's observation statistics from the seed
    episodes and demonstrations (`config.model.normalize_obs`) before any update, then makes
    the `online.demo_pretrain_updates` updates on the demonstrations alone (MoDem's BC
    pretraining; not counted in the update ratio).
    """
    c, o = self.counters, self.config.online
    if not c.get('normalized', True):  # Counters; fine-tuning starts normalized (no key).
      obs = np.concatenate([ep['obs'] for ep in self.buffer.episodes + self.buffer.demos])
      params = set_obs_normalization(self.state.params, obs)
      self.state = self.state.replace(  # Copies: the update donates both trees.
          params=params, ema_params=jax.tree_util.tree_map(jnp.copy, params))
      c['normalized'] = True
    if self.buffer.demos and c.get('pretrain_updates', 0) < o.demo_pretrain_updates:
      self._updates(o.demo_pretrain_updates, 'pretrain_updates', share=1.0)
    self._updates(int(o.update_ratio * c['env_steps']), 'updates',
                  share=demo_share(self.config, c['env_steps']))

  def _updates(self, target: int, counter: str, share: float) -> None:
    """Updates until counters[counter] reaches `target`, `online.updates_per_call` per jitted
    call, a `share` of each batch from the demonstrations (`Buffer.sample`)."""
    c, batch, n = self.counters, self.config.train.batch_size, self.per_call
    c.setdefault(counter, 0)
    while c[counter] + n <= target:
      windows = self.buffer.sample(batch, n, share)
      if n > 1:
        windows = {k: v.reshape((n, batch) + v.shape[1:]) for k, v in windows.items()}
      step = c['updates'] + c.get('pretrain_updates', 0)  # One key per update made.
      self.state, self.metrics = self.update(
          self.state, windows, jax.random.fold_in(self.update_key, step))
      c[counter] += n

  def advance(self) -> None:
    """One wave: its episodes into the buffer, its acting and update time into the counters."""
    start = time.perf_counter()
    planner, episodes = self.wave()
    self.buffer.add(episodes)
    seconds = time.perf_counter() - start
    self.counters['train_seconds'] += seconds
    self.last = (planner, episodes, seconds)

  def _policy(self, first: int, seeds):
    """The policy acting for the wave's episodes (`online.act_mode`: the planner or the actor
    prior alone; EMA parameters, exploration noise)."""
    o = self.config.online
    mesh = (sharding.make_mesh(jax.local_devices())  # Each process acts on its own.
            if self.act_config.eval.data_parallel else None)
    policy = BatchAgentPolicy(self.act_config, self.state.ema_params, o.act_mode,
                              seed=self.config.seed, chunk=o.plan_chunk, mesh=mesh)
    policy.start([goals.Episode('online', first + i, 0, int(s), '', None)
                  for i, s in enumerate(seeds)])
    # Correlated noise is added by `wave` (ar1_noise); white noise inside the jitted plan.
    policy.action_noise = 0.0 if o.exec_noise_corr > 0 else self.noise_std
    return policy

  def _count_winners(self, policy, active) -> None:
    """Which kind of candidate won each acting decision; the last entry counts departures."""
    if policy.last_info is None:
      return
    for info_i in policy.last_info[active]:
      if info_i[0] >= 0:
        self.winners[info_i[0]] += 1
      self.winners[-1] += info_i[2]

  def wave(self):
    """One episode per environment: (planner acted, episodes), by the planner or at random.

    Episodes are dicts of obs [L+1, obs_dim], action [L, A], reward [L], success [L].
    """
    o, n = self.config.online, len(self.envs)
    first, act_dim = self.counters['episodes'], self.config.action_dim
    seeds = envs.episode_seeds(self.config.seed, first + n, 'online')[first:]
    planner = self.learning()
    self.noise_std = executed_noise(self.config, self.counters['env_steps'], self.learn_start)
    policy, rng = None, np.random.default_rng([self.config.seed, first, 17])
    if planner:
      self.catch_up()
      policy = self._policy(first, seeds)
    obs = np.stack([e.reset(seed=int(s))[0] for e, s in zip(self.envs, seeds)])
    # Copies: `obs` rows are overwritten in place by every step below.
    eps = [dict(obs=[np.copy(x)], action=[], reward=[], success=[]) for x in obs]
    active, t = np.ones(n, bool), 0
    noise, noise_rng = np.zeros((n, act_dim)), np.random.default_rng([self.config.seed, first, 29])
    self.winners = np.zeros(len(CANDIDATES) + 1, np.int64)
    self.dense_max = 0.0
    while active.any():
      actions = (policy(obs, t, active) if planner
                 else rng.uniform(-1.0, 1.0, (n, act_dim)).astype(np.float32))
      if planner:
        self._count_winners(policy, active)
        if o.exec_noise_corr > 0:
          noise = ar1_noise(noise, self.noise_std, o.exec_noise_corr, noise_rng)
          actions = np.clip(actions + noise, -1.0, 1.0).astype(np.float32)
      for i in np.flatnonzero(active):
        obs[i], reward, terminated, truncated, info = self.envs[i].step(actions[i])
        self.dense_max = max(self.dense_max, float(reward))
        if o.reward == 'sparse':  # Success only: the case the idea was made for.
          reward = float(info['success'])
        for name, value in (('obs', obs[i]), ('action', actions[i]), ('reward', reward),
                            ('success', info['success'])):
          eps[i][name].append(np.copy(value))
        self.counters['env_steps'] += info['substeps']
        self.bar.update(info['substeps'])
        active[i] = not (terminated or truncated)
      t += 1
      if planner:
        self.catch_up()
        policy.set_params(self.state.ema_params)
    self.counters['episodes'] += n
    return planner, [dict(obs=np.asarray(e['obs'], np.float32),
                          action=np.asarray(e['action'], np.float32),
                          reward=np.asarray(e['reward'], np.float32),
                          success=np.asarray(e['success'], bool)) for e in eps]

  def checkpoint(self) -> None:
    """The buffer file, then the orbax step (environment steps); older buffer files go."""
    step, workdir, manager = self.counters['env_steps'], self.run.workdir, self.run.manager
    self.buffer.save(buffer_path(workdir, step), self.counters)
    self.run.save(self.state, step, self.counters['train_seconds'])
    keep = {f'buffer_{s}.npz' for s in manager.all_steps()}
    for name in os.listdir(os.path.join(workdir, BUFFER_DIR)):
      if name.startswith('buffer_') and name not in keep:
        os.remove(os.path.join(workdir, BUFFER_DIR, name))

  def eval_params(self):
    return self.state.ema_params

  def log(self, before: int) -> None:
    """online.csv (one row per wave), losses.csv (the wave's last update) and TensorBoard."""
    planner, episodes, seconds = self.last
    metrics = {k: float(v) for k, v in sorted(jax.device_get(self.metrics).items())}
    step = self.counters['env_steps']
    if metrics:
      self.run.check_loss(metrics['loss'], f'environment step {step}')
    # Shares of planned decisions: NaN where nothing was planned (random waves, the actor acting).
    decisions = int(self.winners[:-1].sum()) or float('nan')
    acting = {'plan': 'planner', 'actor': 'actor'}[self.config.online.act_mode]
    row = dict(env_steps=step, episodes=self.counters['episodes'],
               updates=self.counters['updates'], acting=acting if planner else 'random',
               episode_return=float(np.mean([e['reward'].sum() for e in episodes])),
               episode_success=float(np.mean([e['success'].any() for e in episodes])),
               max_step_reward=self.dense_max,  # Dense reward, also under a sparse one.
               **{f'won_{k}': float(self.winners[j] / decisions)
                  for j, k in enumerate(CANDIDATES.names())},
               departed=float(self.winners[-1] / decisions),
               exec_noise=executed_noise(self.config, before, self.learn_start)
               if planner else float('nan'),
               env_steps_per_s=(step - before) / seconds)
    run_files.append_csv(os.path.join(self.run.workdir, ONLINE_CSV), row)
    if metrics:  # Losses of the wave's last update, from the first update on.
      run_files.append_csv(os.path.join(self.run.workdir, LOSSES_CSV),
                           dict(env_steps=step, **metrics))
    for k, v in list(row.items())[1:] + [(f'loss/{k}', v) for k, v in metrics.items()]:
      if k != 'acting' and np.isfinite(v):  # NaN marks "not measured" in the CSV only.
        self.run.writer.add_scalar(f'online/{k}', v, step)
    self.bar.set_postfix(updates=self.counters['updates'],
                         success=np.mean([e['success'].any() for e in episodes]))


def train_online(config: ml_collections.ConfigDict, workdir: str,
                 continue_with_changes: bool = False) -> Dict[str, Any]:
  """Online (or offline-to-online) training and evaluation; returns the report.

  Resumes from the latest checkpoint in <workdir>/checkpoints. Writes config.json, online.csv
  (one row per wave: environment steps, updates, training episodes' return and success),
  losses.csv (the wave's last update's losses),
  eval.csv (held-out success every `online.eval_every` environment steps), tb/, online.png,
  episodes.csv, report.json and report.md, like the offline job. A workdir of another config is
  refused before anything is written to it, unless `continue_with_changes` (`train_and_evaluate`).
  """
  validate_config(config)
  envs.check_task(config.task)
  source = check_init_from(config)
  if source is not None:  # Fine-tuning trains on the offline run's data too.
    config.data.update(source.data.to_dict())
  checkpointing.check_workdir(config, workdir, continue_with_changes)  # As it will be saved.
  os.makedirs(workdir, exist_ok=True)
  offline = data.load_for_config(config) if source is not None else None
  if offline is not None:
    runs.check_config_for_data(config, offline)
  if not config.online.update_ratio:  # Once, before any work.
    print('warning: config.online.update_ratio=0: no updates; the agent is evaluated as it '
          f"starts ({'the offline run' if source is not None else 'untrained'})", file=sys.stderr)
  run = runs.Run(config, workdir)
  job = OnlineJob(config, run, source, offline)
  o, c = config.online, job.counters
  if source is not None and c['env_steps'] == 0:  # Held-out success before fine-tuning.
    run.periodic_eval(job.eval_params(), 0)
  runs.loop(run, job, o.env_steps, o.checkpoint_every, o.eval_every)
  job.bar.close()
  final, _, summary, records = run.final_evaluation(job.eval_params(), c['env_steps'])
  report = _report(job, final, summary, run.commit)
  return run.write_report(report, _summary_md(report), records)


def _report(job: OnlineJob, final, summary, commit) -> Dict[str, Any]:
  config, c = job.config, job.counters
  curve = [dict(env_steps=int(r['step']), episodes=int(r['episodes']),
                success_rate=float(r['success_rate']), ci95=[float(r['ci_lo']), float(r['ci_hi'])],
                mean_return=float(r['mean_return']))
           for r in run_files.read_csv(os.path.join(job.run.workdir, runs.EVAL_CSV))]
  return {
      'task': config.task, 'mode': 'fine-tune' if job.source is not None else 'from scratch',
      'init_from': config.online.init_from or None,
      'env_steps': c['env_steps'], 'updates': c['updates'], 'episodes': c['episodes'],
      'train_seconds': c['train_seconds'],
      'env_steps_per_s': c['env_steps'] / c['train_seconds'],
      'success_rate': final['success_rate'], 'success_ci95': final['success_ci95'],
      'mean_return': final['mean_return'], 'eval_episodes': config.eval.episodes,
      'eval_seeds': list(config.eval.seeds), 'evaluation': summary, 'curve': curve,
      'num_params': count_params(job.state.ema_params),
      'demos': len(job.buffer.demos), 'reward': config.online.reward,
      'first_training_success': _first_success(job.run.workdir),
      'buffer': {'online_episodes': len(job.buffer.episodes),
                 'offline_episodes': (job.buffer.offline.num_episodes
                                      if job.buffer.offline is not None else 0)},
      **runs.provenance(config, commit),
  }


def _first_success(workdir: str) -> Optional[int]:
  """Environment steps (simulator steps) at the end of the first wave with a successful
  training episode (None: none succeeded), from online.csv."""
  for row in run_files.read_csv(os.path.join(workdir, ONLINE_CSV)):
    if float(row['episode_success']) > 0:
      return int(row['env_steps'])
  return None


def _summary_md(report: Dict[str, Any]) -> str:
  """report.md: what ran, the held-out curve against environment steps, the final evaluation."""
  start = (f"fine-tuned from `{report['init_from']}` (its dataset and "
           f"{report['buffer']['online_episodes']} online episodes in the buffer)"
           if report['init_from'] else f"from scratch ({report['buffer']['online_episodes']} "
           'online episodes, seed episodes of random actions first)' if not report['demos']
           else f"from scratch with {report['demos']} demonstrations "
           f"({report['buffer']['online_episodes']} online episodes)")
  first = report['first_training_success']
  start += (f"; first successful training episode by {first:,} environment steps"
            if first is not None else '; no training episode succeeded')
  lines = [f"{report['env_steps']:,} environment steps, {report['updates']:,} updates, {start}; "
           f"{report['train_seconds']:.0f} s acting and training "
           f"({report['env_steps_per_s']:.1f} environment steps/s with updates and compilation, "
           f"evaluations excluded); {report['num_params']:,} parameters.", '']
  if report['curve']:
    lines += ['Planner (EMA parameters, no exploration noise) on held-out goals during training:',
              '', '| environment steps | episodes | success | 95% CI | mean return to first '
              'success |',
              '| --- | --- | --- | --- | --- |']
    lines += [f"| {r['env_steps']:,} | {r['episodes']} | {r['success_rate']:.2f} | "
              f"[{r['ci95'][0]:.2f}, {r['ci95'][1]:.2f}] | {r['mean_return']:.1f} |"
              for r in report['curve']]
    lines.append('')
  return runs.summary_md(f"LD-MPC online on {report['task']}", lines, report,
                         'Final evaluation, EMA parameters: ', 'training')
