"""Online and offline-to-online training: the planner acts, its episodes feed the replay buffer.

`train_online(config, workdir)` is the main job's online mode (`config.online.enabled`;
experiments/configs/door_open_online.py). N = `online.num_envs` environments run one episode each
in lockstep (a wave); episodes run their full `online.episode_steps` environment steps, as the
scripted data do, and start from the goals of MT1 seed `config.data.seed`. From scratch, the
waves of the first `online.seed_steps` environment steps act with uniform random actions; after
them the agent acts with its planner and EMA parameters (one jitted plan per environment, or
`online.plan_chunk` environments per vmap, `agent.BatchAgentPolicy`), with the exploration noise
`online.action_noise_std` / `online.prior_noise_std` on its candidates (`acting_config`), which
evaluation never uses. Updates interleave with acting: once learning has started, after every
decision updates run until floor(`online.update_ratio` x environment steps) have been made, so
from scratch the seed steps' share comes at once (TD-MPC2 pretrains on its seed data likewise).
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
import time
from typing import Any, Dict, List, Optional

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import tqdm
from tensorboardX import SummaryWriter

from ld_mpc_jax import checkpointing, data, envs, run_files, sharding, train
from ld_mpc_jax.agent import BatchAgentPolicy
from ld_mpc_jax.config_checks import validate_config
from ld_mpc_jax.envs import goals
from ld_mpc_jax.models import count_params, set_obs_normalization
from ld_mpc_jax.search import CANDIDATE_KINDS
from ld_mpc_jax.train_state import create_train_state, make_multi_update, make_update

ONLINE_CSV = 'online.csv'
LOSSES_CSV = 'losses.csv'
BUFFER_DIR = 'online'


def acting_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
  """A copy of config for the planner while acting: `config.online`'s exploration noise on its
  candidates and its acting pessimism (`online.act_pessimism`; evaluation keeps
  `plan.pessimism`): unfamiliar states are model error offline, opportunity online."""
  c = ml_collections.ConfigDict(config.to_dict())
  c.plan.action_noise_std = config.online.action_noise_std
  c.plan.prior_noise_std = config.online.prior_noise_std
  c.plan.pessimism = config.online.act_pessimism
  return c


def executed_noise(config: ml_collections.ConfigDict, env_steps: int, learn_start: int) -> float:
  """Std of the noise on the executed action at `env_steps`: linear from
  `online.exec_noise_start` when the planner starts acting to `online.exec_noise_end` at
  `online.env_steps`."""
  o = config.online
  frac = np.clip((env_steps - learn_start) / max(o.env_steps - learn_start, 1), 0.0, 1.0)
  return float(o.exec_noise_start + frac * (o.exec_noise_end - o.exec_noise_start))


def check_init_from(config: ml_collections.ConfigDict) -> Optional[ml_collections.ConfigDict]:
  """The config of the offline run `online.init_from` (None: from scratch).

  Raises a one-line ValueError when it is not a training workdir with a checkpoint, or when its
  networks differ from config's (the parameters would not fit).
  """
  path = config.online.init_from
  if not path:
    return None
  try:
    source = checkpointing.load_config(path)
  except FileNotFoundError as err:
    raise ValueError(f'config.online.init_from: {err}') from None
  if checkpointing.checkpoint_manager(path).latest_step() is None:
    raise ValueError(f'config.online.init_from={path!r} has no checkpoint')
  shapes = lambda c: jax.tree_util.tree_map(lambda x: x.shape, checkpointing.abstract_state(c))
  if shapes(source) != shapes(config):
    fields = [f'model.{k}' for k in config.model if k != 'dropout' and  # JSON: lists = tuples.
              json.dumps(source.model.get(k)) != json.dumps(config.model[k])]
    raise ValueError(f'config.online.init_from={path!r} has other networks than this config '
                     f'(differs in {", ".join(fields) or "objective/horizon"})')
  return source


class Buffer:
  """The replay buffer of an online run: the offline dataset (if any) and the online episodes.

  Episodes are dicts of obs [L+1, obs_dim], action [L, A], reward [L], success [L] (float32,
  bool); windows are sampled uniformly over both (`data.ReplayBuffer`) with one persistent
  generator, whose state the checkpoint keeps.
  """

  def __init__(self, seq_len: int, offline: Optional[data.Dataset], seed: int):
    self.seq_len, self.offline = seq_len, offline
    self.episodes: List[Dict[str, np.ndarray]] = []
    self.rng = np.random.default_rng([seed, 23])
    self._sampler = None

  def add(self, episodes: List[Dict[str, np.ndarray]]) -> None:
    self.episodes.extend(episodes)
    self._sampler = None

  def sample(self, batch_size: int) -> Dict[str, np.ndarray]:
    if self._sampler is None:
      old = [self.offline.episode(e) for e in range(self.offline.num_episodes)] if (
          self.offline is not None) else []
      # default_rng(Generator) is that generator: the sampler draws from self.rng.
      self._sampler = data.ReplayBuffer(data.Dataset.from_episodes(old + self.episodes),
                                        self.seq_len, seed=self.rng)
    return self._sampler.sample(batch_size)

  def save(self, path: str, counters: Dict[str, Any]) -> None:
    """Online episodes and `counters` to `path` (.npz, atomic; `data.save`)."""
    meta = dict(online=counters, sampler_rng=self.rng.bit_generator.state)
    data.save(data.Dataset.from_episodes(self.episodes, metadata=meta), path)

  def load(self, path: str) -> Dict[str, Any]:
    """Replaces the online episodes and the sampler state with `path`'s; returns its counters."""
    ds = data.load(path)
    self.episodes = [ds.episode(e) for e in range(ds.num_episodes)]
    self.rng.bit_generator.state = ds.metadata['sampler_rng']
    self._sampler = None
    return ds.metadata['online']


def buffer_path(workdir: str, step: int) -> str:
  return os.path.join(workdir, BUFFER_DIR, f'buffer_{step}.npz')


class _Run:
  """One online run's state: TrainState, buffer, counters, environments, writers."""

  def __init__(self, config, workdir):
    self.config, self.workdir, o = config, workdir, config.online
    self.source = check_init_from(config)
    if self.source is not None:  # Fine-tuning trains on the offline run's data too.
      config.data.update(self.source.data.to_dict())
    os.makedirs(workdir, exist_ok=True)
    offline = data.load_for_config(config) if self.source is not None else None
    if offline is not None:
      train.check_config_for_data(config, offline)
    checkpointing.save_config(config, workdir)
    self.buffer = Buffer(train.window_length(config), offline, config.seed)
    self.manager = checkpointing.checkpoint_manager(workdir, config.train.max_checkpoints)
    self.counters = dict(env_steps=0, updates=0, episodes=0, train_seconds=0.0)
    self.state = checkpointing.restore_latest(self.manager, config)
    if self.state is not None:  # Resume: the buffer file of the same step.
      step = self.manager.latest_step()
      if not os.path.exists(buffer_path(workdir, step)):
        raise FileNotFoundError(f'checkpoint {step} has no {buffer_path(workdir, step)}')
      self.counters = self.buffer.load(buffer_path(workdir, step))
    elif self.source is not None:
      self.state = checkpointing.restore_latest(
          checkpointing.checkpoint_manager(o.init_from), config)
    else:  # From scratch; observation statistics come with the seed data (catch_up).
      self.state = create_train_state(config, jax.random.key(config.seed))
      self.counters['normalized'] = not config.model.get('normalize_obs', False)
    self.learn_start = 0 if self.source is not None else o.seed_steps
    self.per_call = o.updates_per_call
    self.update = (make_update(config) if self.per_call == 1
                   else make_multi_update(config, self.per_call))
    self.update_key = jax.random.key(config.seed + 1)
    self.act_config = acting_config(config)
    self.envs = [envs.make_env(config.task, seed=config.data.seed,
                               action_repeat=config.eval.action_repeat,
                               max_episode_steps=o.episode_steps) for _ in range(o.num_envs)]
    self.writer = SummaryWriter(os.path.join(workdir, 'tb')) if run_files.primary() else (
        run_files.NoWriter())
    self.metrics = {}
    self.bar = tqdm.tqdm(total=o.env_steps, initial=self.counters['env_steps'], desc='online',
                         unit='env step', dynamic_ncols=True)

  def learning(self) -> bool:
    return self.counters['env_steps'] >= self.learn_start

  def catch_up(self) -> None:
    """Updates until floor(update_ratio x environment steps) have been made.

    From scratch, the first call sets the encoder's observation statistics from the seed
    episodes (`config.model.normalize_obs`) before any update.
    """
    c = self.counters
    if not c.get('normalized', True):
      obs = np.concatenate([ep['obs'] for ep in self.buffer.episodes])
      params = set_obs_normalization(self.state.params, obs)
      self.state = self.state.replace(  # Copies: the update donates both trees.
          params=params, ema_params=jax.tree_util.tree_map(jnp.copy, params))
      c['normalized'] = True
    target, batch, n = (int(self.config.online.update_ratio * c['env_steps']),
                        self.config.train.batch_size, self.per_call)
    while c['updates'] + n <= target:  # `online.updates_per_call` updates per jitted call.
      windows = self.buffer.sample(batch * n)
      if n > 1:
        windows = {k: v.reshape((n, batch) + v.shape[1:]) for k, v in windows.items()}
      self.state, self.metrics = self.update(
          self.state, windows, jax.random.fold_in(self.update_key, c['updates']))
      c['updates'] += n

  def wave(self):
    """One episode per environment: (planner acted, episodes), by the planner or at random."""
    o, n = self.config.online, len(self.envs)
    first, act_dim = self.counters['episodes'], self.config.action_dim
    seeds = envs.episode_seeds(self.config.seed, first + n, 'online')[first:]
    planner = self.learning()
    policy, rng = None, np.random.default_rng([self.config.seed, first, 17])
    if planner:
      self.catch_up()
      mesh = (sharding.make_mesh(jax.local_devices())  # Each process acts on its own.
              if self.act_config.eval.get('data_parallel', False) else None)
      policy = BatchAgentPolicy(self.act_config, self.state.ema_params, 'plan',
                                seed=self.config.seed, chunk=o.plan_chunk, mesh=mesh)
      policy.start([goals.Episode('online', first + i, 0, int(s), '', None)
                    for i, s in enumerate(seeds)])
      policy.action_noise = executed_noise(self.config, self.counters['env_steps'],
                                           self.learn_start)
    obs = np.stack([e.reset(seed=int(s))[0] for e, s in zip(self.envs, seeds)])
    eps = [dict(obs=[x], action=[], reward=[], success=[]) for x in obs]
    active, t = np.ones(n, bool), 0
    # Which kind of candidate won each acting decision; the last entry counts departures.
    self.winners = np.zeros(len(CANDIDATE_KINDS) + 1, np.int64)
    self.dense_max = 0.0
    while active.any():
      actions = (policy(obs, t, active) if planner
                 else rng.uniform(-1.0, 1.0, (n, act_dim)).astype(np.float32))
      if planner and policy.last_info is not None:
        for info_i in policy.last_info[active]:
          if info_i[0] >= 0:
            self.winners[info_i[0]] += 1
          self.winners[-1] += info_i[2]
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
    step = self.counters['env_steps']
    self.buffer.save(buffer_path(self.workdir, step), self.counters)
    train.save_checkpoint(self.workdir, self.manager, self.state, step,
                          self.counters['train_seconds'])
    keep = {f'buffer_{s}.npz' for s in self.manager.all_steps()}
    for name in os.listdir(os.path.join(self.workdir, BUFFER_DIR)):
      if name.startswith('buffer_') and name not in keep:
        os.remove(os.path.join(self.workdir, BUFFER_DIR, name))

  def evaluate(self) -> None:
    if self.config.eval.episodes > 0:
      train.periodic_eval(self.config, self.state.ema_params, self.counters['env_steps'],
                          self.workdir, self.writer)
      write_plots(self.workdir)

  def log(self, planner: bool, episodes, seconds: float, steps: int, before_steps: int) -> None:
    metrics = {k: float(v) for k, v in sorted(jax.device_get(self.metrics).items())}
    if metrics and not np.isfinite(metrics['loss']):
      raise FloatingPointError(
          f"non-finite loss {metrics['loss']} at environment step {self.counters['env_steps']}; "
          f'stopping. The last good checkpoint (step {self.manager.latest_step()}) is kept.')
    step = self.counters['env_steps']
    decisions = max(int(self.winners[:-1].sum()), 1)
    row = dict(env_steps=step, episodes=self.counters['episodes'],
               updates=self.counters['updates'], acting='planner' if planner else 'random',
               episode_return=float(np.mean([e['reward'].sum() for e in episodes])),
               episode_success=float(np.mean([e['success'].any() for e in episodes])),
               max_step_reward=self.dense_max,  # Dense reward, also under a sparse one.
               **{f'won_{k}': float(self.winners[j] / decisions)
                  for j, k in enumerate(CANDIDATE_KINDS)},
               departed=float(self.winners[-1] / decisions),
               exec_noise=executed_noise(self.config, before_steps, self.learn_start)
               if planner else float('nan'),
               env_steps_per_s=steps / seconds)
    run_files.append_csv(os.path.join(self.workdir, ONLINE_CSV), row)
    if metrics:  # Losses of the wave's last update, from the first update on.
      run_files.append_csv(os.path.join(self.workdir, LOSSES_CSV), dict(env_steps=step, **metrics))
    for k, v in list(row.items())[1:] + [(f'loss/{k}', v) for k, v in metrics.items()]:
      if k != 'acting':
        self.writer.add_scalar(f'online/{k}', v, step)


def train_online(config: ml_collections.ConfigDict, workdir: str) -> Dict[str, Any]:
  """Online (or offline-to-online) training and evaluation; returns the report.

  Resumes from the latest checkpoint in <workdir>/checkpoints. Writes config.json, online.csv
  (one row per wave: environment steps, updates, training episodes' return and success),
  losses.csv (the wave's last update's losses),
  eval.csv (held-out success every `online.eval_every` environment steps), tb/, online.png,
  episodes.csv, report.json and report.md, like the offline job.
  """
  validate_config(config)
  envs.check_task(config.task)
  commit = run_files.git_commit()
  run = _Run(config, workdir)
  o, c = config.online, run.counters
  if run.source is not None and c['env_steps'] == 0:  # Held-out success before fine-tuning.
    run.evaluate()
  while c['env_steps'] < o.env_steps:
    start, before = time.perf_counter(), c['env_steps']
    planner, episodes = run.wave()
    run.buffer.add(episodes)
    seconds = time.perf_counter() - start
    c['train_seconds'] += seconds
    run.log(planner, episodes, seconds, c['env_steps'] - before, before)
    run.bar.set_postfix(updates=c['updates'],
                        success=np.mean([e['success'].any() for e in episodes]))
    if c['env_steps'] // o.eval_every > before // o.eval_every and c['env_steps'] < o.env_steps:
      run.evaluate()  # The last one is the final evaluation.
    if (c['env_steps'] // o.checkpoint_every > before // o.checkpoint_every
        or c['env_steps'] >= o.env_steps):
      run.checkpoint()
  run.bar.close()
  final, baselines, summary, records = train.final_evaluation(
      config, run.state.ema_params, c['env_steps'], workdir, run.writer)
  run.writer.close()
  report = _report(run, final, summary, commit)
  if run_files.primary():
    with open(os.path.join(workdir, 'report.json'), 'w') as f:
      json.dump(report, f, indent=2)
    with open(os.path.join(workdir, 'report.md'), 'w') as f:
      f.write(_summary_md(report))
  write_plots(workdir)
  report['records'] = records
  return report


def _report(run: _Run, final, summary, commit) -> Dict[str, Any]:
  config, c = run.config, run.counters
  curve = [dict(env_steps=int(r['step']), episodes=int(r['episodes']),
                success_rate=float(r['success_rate']), ci95=[float(r['ci_lo']), float(r['ci_hi'])],
                mean_return=float(r['mean_return']))
           for r in run_files.read_csv(os.path.join(run.workdir, 'eval.csv'))]
  return {
      'task': config.task, 'mode': 'fine-tune' if run.source is not None else 'from scratch',
      'init_from': config.online.init_from or None,
      'env_steps': c['env_steps'], 'updates': c['updates'], 'episodes': c['episodes'],
      'train_seconds': c['train_seconds'],
      'env_steps_per_s': c['env_steps'] / c['train_seconds'],
      'success_rate': final['success_rate'], 'success_ci95': final['success_ci95'],
      'mean_return': final['mean_return'], 'eval_episodes': config.eval.episodes,
      'eval_seeds': list(config.eval.seeds), 'evaluation': summary, 'curve': curve,
      'num_params': count_params(run.state.ema_params),
      'buffer': {'online_episodes': len(run.buffer.episodes),
                 'offline_episodes': (run.buffer.offline.num_episodes
                                      if run.buffer.offline is not None else 0)},
      'config': json.loads(config.to_json_best_effort()),
      'versions': run_files.versions(), 'git_commit': commit,
  }


def _summary_md(report: Dict[str, Any]) -> str:
  """report.md: what ran, the held-out curve against environment steps, the final evaluation."""
  start = (f"fine-tuned from `{report['init_from']}` (its dataset and "
           f"{report['buffer']['online_episodes']} online episodes in the buffer)"
           if report['init_from'] else f"from scratch ({report['buffer']['online_episodes']} "
           'online episodes, seed episodes of random actions first)')
  lines = [f"# LD-MPC online on {report['task']}", '',
           f"{report['env_steps']:,} environment steps, {report['updates']:,} updates, {start}; "
           f"{report['train_seconds']:.0f} s acting and training "
           f"({report['env_steps_per_s']:.1f} environment steps/s with updates and compilation, "
           f"evaluations excluded); {report['num_params']:,} parameters.", '']
  if report['curve']:
    lines += ['Planner (EMA parameters, no exploration noise) on held-out goals during training:',
              '', '| environment steps | episodes | success | 95% CI | mean return |',
              '| --- | --- | --- | --- | --- |']
    lines += [f"| {r['env_steps']:,} | {r['episodes']} | {r['success_rate']:.2f} | "
              f"[{r['ci95'][0]:.2f}, {r['ci95'][1]:.2f}] | {r['mean_return']:.1f} |"
              for r in report['curve']]
    lines.append('')
  lines += train.evaluation_md_lines(report, 'Final evaluation, EMA parameters: ', 'training')
  return '\n'.join(lines) + '\n'


def write_plots(workdir: str) -> None:
  """online.png: success and return against environment steps (training episodes and held-out
  evaluations), and the loss."""
  waves = run_files.read_csv(os.path.join(workdir, ONLINE_CSV))
  if not run_files.primary() or not waves:
    return
  import matplotlib
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt
  evals = run_files.read_csv(os.path.join(workdir, 'eval.csv'))
  col = lambda rows, name: np.array([float(r[name]) for r in rows])
  x, ex = col(waves, 'env_steps'), col(evals, 'step')
  fig, axes = plt.subplots(1, 3, figsize=(15, 4))
  axes[0].plot(x, col(waves, 'episode_success'), '.-', alpha=0.6,
               label='training episodes (exploration noise)')
  if evals:
    axes[0].plot(ex, col(evals, 'success_rate'), 'o-', label='planner, held-out goals')
    axes[0].fill_between(ex, col(evals, 'ci_lo'), col(evals, 'ci_hi'), alpha=0.2)
    axes[1].plot(ex, col(evals, 'mean_return'), 'o-', label='planner, held-out goals')
  axes[0].set_ylabel('success rate'); axes[0].set_ylim(-0.02, 1.02)
  axes[1].plot(x, col(waves, 'episode_return'), '.-', alpha=0.6, label='training episodes')
  axes[1].set_ylabel('episode return')
  losses = run_files.read_csv(os.path.join(workdir, LOSSES_CSV))
  if losses:
    axes[2].plot(col(losses, 'env_steps'), col(losses, 'loss'), '.-')
    axes[2].set_yscale('log')
  axes[2].set_ylabel('loss (last update of each wave)')
  for ax in axes:
    ax.set_xlabel('environment step')
  axes[0].legend(); axes[1].legend()
  fig.tight_layout(); fig.savefig(os.path.join(workdir, 'online.png'), dpi=100)
  plt.close(fig)
