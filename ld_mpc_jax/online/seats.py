"""The training seeds of an online run (ld_mpc_jax.online.job, `train.num_seeds`): each seed's
run directory, settings, buffer and environments (`Seat`), one wave of their episodes
(`run_wave`), each seed's episodes while they run (`SeatWave`) and what the wave left
(`WaveRecord`, which runs.online_report.log_wave writes down). What a wave acts with is fixed
at its start (`WaveSchedule`) and passed in, and the job's counters change after it: during a
wave only the learner's parameters advance (ld_mpc_jax.online.learner), and the policy acts
with them."""

import dataclasses
from typing import Any, List, Optional, Sequence, Tuple

import jax
import numpy as np

from ld_mpc_jax import data, envs
from ld_mpc_jax.ops import sharding
from ld_mpc_jax.plan.agent import BatchAgentPolicy
from ld_mpc_jax.plan.seeds_agent import SeedsAgentPolicy
from ld_mpc_jax.data.online_buffer import Buffer
from ld_mpc_jax.data.replay import window_length
from ld_mpc_jax.online.schedule import ar1_noise
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.envs import goals
from ld_mpc_jax.plan.search import CANDIDATES


@dataclasses.dataclass(frozen=True)
class WaveSchedule:
  """What a wave acts with, fixed at its start from the environment steps so far."""
  mode: str  # 'random' (seed waves), 'actor' or 'plan' (OnlineJob.acting_mode).
  noise_std: float  # Std of the noise on the executed action (ActingSchedule.executed_noise).
  intrinsic: Any = None  # The planner's intrinsic term's weights (ActingSchedule.intrinsic).


@dataclasses.dataclass(frozen=True)
class WaveRecord:
  """One seed's wave once it ended: its episodes (dicts of obs [L+1, obs_dim], action [L, A],
  reward [L], success [L]), which kind of candidate won each planned decision (counts per
  CANDIDATES kind, the last entry counting departures from the actor prior), the first-action
  spreads [D, 2] and the proposal's share of the first round's elites [D] of the planned
  decisions (agent.NO_PLAN_INFO), and the largest dense step reward."""
  episodes: List[dict]
  winners: np.ndarray
  spreads: np.ndarray
  dense_max: float
  elites: np.ndarray


class Seat:
  """One training seed of an online run: its run directory, settings, buffer, environments and
  what its last wave did; the parameters live in the learner's stacked TrainStates."""

  def __init__(self, run, online: OnlineSettings, model: ModelSettings,
               offline: Optional[data.Dataset], index: int, keep_plans: bool = False):
    """`run`: the seed's run directory (runs.loop.Run of the seed's plan, whose config it saves);
    `online`: the seed's settings (OnlineSettings.from_config of its config: its seed, task and
    training goals); `model`: the run's (whether the progress reward and the exploration value
    exist); `keep_plans`: the planner's chosen sequences go into the buffer with its episodes
    (`loss.act_target='planned'`)."""
    self.run, self.online, self.index = run, online, index
    self.novelty = model.novelty  # config.loss.w_novelty > 0: the act_novelty column.
    self.buffer = Buffer(window_length(online.horizon), offline, online.seed,
                         online.demonstrations(), progress=model.progress,
                         plan_shape=(model.horizon, model.action_dim) if keep_plans else None)
    self.envs = [envs.make_env(online.task, seed=online.goal_seed,
                               action_repeat=online.action_repeat,
                               max_episode_steps=online.episode_steps,
                               random_goals=online.train_goals == 'random')
                 for _ in range(online.num_envs)]
    self.update_key = jax.random.key(online.seed + 1)


def run_wave(seats: Sequence[Seat], schedule: WaveSchedule, acting, online: OnlineSettings,
             action_dim: int, counters: dict, learner, bar,
             data_parallel: bool = False) -> Tuple[List[WaveRecord], int]:
  """One episode per environment of every seed, in lockstep, acting as `schedule` says (with
  the `acting` policy settings); returns each seat's `WaveRecord` and the environment steps of
  one seed. `counters`: the run's environment steps and episodes before the wave; `learner`
  (online.learner.Learner) makes the updates the steps call for, dispatched before each step
  so that they run while MuJoCo steps, and the planner acts with its newest parameters; `bar`
  counts the steps."""
  planner, done = schedule.mode != 'random', counters['env_steps']
  if planner:
    learner.catch_up(done)
  waves = [SeatWave(seat, online, action_dim, counters['episodes'], schedule) for seat in seats]
  policy = (WavePolicy(acting, online, seats, learner, schedule, waves, data_parallel)
            if planner else None)
  t, steps, none = 0, 0, [None] * len(waves)
  acting_with, carry = (policy.params(learner), None) if planner else (None, None)
  while waves[0].active.any():  # The seeds' episodes have the same lengths.
    actions, infos, sequences, carry = (policy(acting_with[1], [w.obs for w in waves], t,
                                               waves[0].active, carry)
                                        if planner else (none, none, none, None))
    if planner:  # The updates these steps call for, dispatched to run while they step.
      learner.catch_up(done + steps + waves[0].upcoming())
    taken = [w.step(a, i, s) for w, a, i, s in zip(waves, actions, infos, sequences)]
    steps += taken[0]
    bar.update(taken[0])
    t += 1
    if planner:
      learner.catch_up(done + steps)
      acting_with = policy.params(learner, acting_with)
  return [w.finish() for w in waves], steps


class WavePolicy:
  """The policy acting for every seed's episodes of a wave (EMA parameters, exploration
  noise): one seed acts as a single run does (`BatchAgentPolicy`, `online.plan_chunk`); several
  act in one call per environment and device, vmapped over the device's seeds
  (`SeedsAgentPolicy`)."""

  def __init__(self, acting, o: OnlineSettings, seats: Sequence[Seat], learner,
               schedule: WaveSchedule, waves, data_parallel: bool = False):
    """`acting`: the policy's settings (eval.spec.ActSettings, the acting planner's); `learner`:
    whose EMA parameters it acts with; `data_parallel`: one seed's environments split over the
    devices (`eval.data_parallel`)."""
    self.single = len(seats) == 1
    # Correlated noise is added by `SeatWave.step` (ar1_noise); white noise inside the plan.
    keep = schedule.mode == 'plan' and seats[0].buffer.plan_shape is not None
    knobs = dict(action_noise=0.0 if o.exec_noise_corr > 0 else schedule.noise_std,
                 intrinsic=schedule.intrinsic,  # The planner's intrinsic term's weights.
                 keep_sequences=keep)  # The planner's sequences, for the proposal's targets.
    if self.single:
      mesh = (sharding.make_mesh(jax.local_devices())  # Each process acts on its own.
              if data_parallel else None)
      self.inner = BatchAgentPolicy(acting, learner.views()[0], schedule.mode,
                                    seed=seats[0].online.seed, chunk=o.plan_chunk,
                                    mesh=mesh, **knobs)
      self.inner.start(waves[0].episodes)
    else:
      self.inner = SeedsAgentPolicy(acting, learner.group_ema_params(), schedule.mode,
                                    [seat.online.seed for seat in seats], learner.groups,
                                    **knobs)
      self.inner.start([w.episodes for w in waves])

  def __call__(self, params, obs, t: int, active: np.ndarray, carry):
    """obs: each seed's [N, obs_dim] -> (each seed's actions [N, A], infos [N, 6], planned
    sequences [N, H, A] or None; the warm-start carry for the next decision). `params` from
    `params()`, `carry` None at the wave's first decision; nothing is written on the policy."""
    if self.single:
      actions, infos, sequences, carry = self.inner.decide(params, obs[0], t, active, carry)
      return [actions], [infos], [sequences], carry
    actions, infos, sequences, carry = self.inner.decide(params, np.stack(obs), t, active, carry)
    return (list(actions), list(infos),
            list(sequences) if sequences is not None else [None] * len(actions), carry)

  def params(self, learner, last=None) -> tuple:
    """(the learner's current EMA parameters, those as the policy acts with them), prepared
    again only when they changed since `last` (the pair this returned before): replicating
    over a mesh copies them to every device."""
    source = learner.views()[0] if self.single else learner.group_ema_params()
    if last is not None and source is last[0]:
      return last
    return source, self.inner.prepare(source)


class SeatWave:
  """One seed's episodes of a wave while they run: its environments, observations, policy,
  noise and what each episode recorded."""

  def __init__(self, seat: Seat, online: OnlineSettings, action_dim: int, first: int,
               schedule: WaveSchedule):
    n, seed = len(seat.envs), seat.online.seed
    self.seat, self.online, self.schedule, self.action_dim = seat, online, schedule, action_dim
    seeds = envs.episode_seeds(seed, first + n, 'online')[first:]
    self.episodes = [goals.Episode('online', first + i, 0, int(s), '', None)
                     for i, s in enumerate(seeds)]
    self.rng = np.random.default_rng([seed, first, 17])
    self.obs = np.stack([e.reset(seed=int(s))[0] for e, s in zip(seat.envs, seeds)])
    # Copies: `obs` rows are overwritten in place by every step below.
    self.eps = [dict(obs=[np.copy(x)], action=[], reward=[], success=[]) for x in self.obs]
    self.plans = [[] for _ in self.obs]  # The planner's sequences, where they are kept.
    self.active = np.ones(n, bool)
    self.noise = np.zeros((n, action_dim))
    self.noise_rng = np.random.default_rng([seed, first, 29])
    self.winners = np.zeros(len(CANDIDATES) + 1, np.int64)
    # Each planned decision's first-action spreads [2] and its proposal's share of the elites.
    self.spreads, self.elites, self.dense_max = [], [], 0.0

  def upcoming(self) -> int:
    """Environment steps the next `step` will take, summed over the active environments (0 when
    an environment cannot tell: the updates then wait for the steps, as before)."""
    envs_ = [self.seat.envs[i] for i in np.flatnonzero(self.active)]
    if not all(hasattr(e, 'next_substeps') for e in envs_):
      return 0
    return sum(e.next_substeps() for e in envs_)

  def step(self, actions: Optional[np.ndarray], infos: Optional[np.ndarray],
           sequences: Optional[np.ndarray] = None) -> int:
    """One decision in each active environment, with the policy's `actions` [N, A] and
    `infos` [N, 6] (None: uniform random actions) and the planner's chosen `sequences`
    [N, H, A] where they are kept; returns the environment steps taken, summed over the
    environments (`info['substeps']`)."""
    o, seat, n = self.online, self.seat, len(self.seat.envs)
    if actions is not None:
      self._count_winners(infos)
      if o.exec_noise_corr > 0:
        self.noise = ar1_noise(self.noise, self.schedule.noise_std, o.exec_noise_corr,
                               self.noise_rng)
        actions = np.clip(actions + self.noise, -1.0, 1.0).astype(np.float32)
    else:
      actions = self.rng.uniform(-1.0, 1.0, (n, self.action_dim)).astype(np.float32)
    substeps = 0
    for i in np.flatnonzero(self.active):
      self.obs[i], reward, terminated, truncated, info = seat.envs[i].step(actions[i])
      self.dense_max = max(self.dense_max, float(reward))
      if o.reward == 'sparse':  # Success only: the case the idea was made for.
        reward = float(info['success'])
      for name, value in (('obs', self.obs[i]), ('action', actions[i]), ('reward', reward),
                          ('success', info['success'])):
        self.eps[i][name].append(np.copy(value))
      if sequences is not None:
        self.plans[i].append(np.asarray(sequences[i], np.float32))
      substeps += info['substeps']
      self.active[i] = not (terminated or truncated)
    return substeps

  def _count_winners(self, infos) -> None:
    """Which kind of candidate won each acting decision (the last entry counts departures), and
    the spreads of its candidates' first actions and the proposal's share of its elites."""
    if infos is None:
      return
    for info_i in infos[self.active]:
      if info_i[0] >= 0:
        self.winners[int(info_i[0])] += 1
        self.spreads.append(info_i[4:6])
        self.elites.append(info_i[6])
      self.winners[-1] += int(info_i[2])

  def finish(self) -> WaveRecord:
    episodes = [dict(obs=np.asarray(e['obs'], np.float32),
                     action=np.asarray(e['action'], np.float32),
                     reward=np.asarray(e['reward'], np.float32),
                     success=np.asarray(e['success'], bool)) for e in self.eps]
    for episode, plans in zip(episodes, self.plans):
      if plans:  # Every decision of a planner wave was planned.
        episode['plan'] = np.stack(plans)
    return WaveRecord(episodes, self.winners.copy(),
                      np.asarray(self.spreads, np.float64).reshape(-1, 2), self.dense_max,
                      np.asarray(self.elites, np.float64))
