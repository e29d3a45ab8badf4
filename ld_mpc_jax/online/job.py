"""An online run's job (`runs.loop.Job`): one wave of episodes and its updates per advance.

`OnlineJob` holds every training seed's TrainState stacked on a seed axis, one `Seat` per seed
(ld_mpc_jax.online.seats), the shared counters and the acting schedule; `runs.online.train_online`
builds it and drives it with `runs.loop`. Each wave acts with a `WaveSchedule` fixed at its
start; the updates it calls for interleave with its decisions (`catch_up`).
"""

import dataclasses
import os
import time
from typing import Any, Callable, Dict, Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax import data
from ld_mpc_jax.data.online_buffer import BUFFER_DIR, buffer_path
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import create_train_state, make_seeds_update, stack_states
from ld_mpc_jax.model.models import set_obs_normalization
from ld_mpc_jax.online.schedule import ActingSchedule
from ld_mpc_jax.online.seats import Seat, SeatRuns, SeatWave, WavePolicy, WaveSchedule
from ld_mpc_jax.ops.seed_groups import SeedGroups

class OnlineJob:
  """An online run as a `runs.loop.Job`: each advance is one wave of episodes and its updates.

  Holds the TrainState of every training seed stacked on a leading seed axis (one seed:
  [1, ...]; `train.num_seeds`), in one stack per device (`states`; `train.seed_devices`
  groups, `ops.seed_groups`), one `Seat` per seed (run directory, buffer, environments), and
  the counters (environment steps: the job's progress), which the seeds share: they act in
  lockstep, each on its own episodes, and the update is vmapped over each group's seeds
  (`train_state.make_seeds_update`), so each seed's run is the one it would make alone.
  """

  def __init__(self, plans: Sequence, seed_runs: Sequence, offline: Optional[data.Dataset],
               bar: Callable[[int], Any], sources: Optional[Sequence[str]] = None):
    """`plans`: each training seed's SeedPlan (runs.seed_plan.seed_plans), which differ in their
    seeds (and sources) only; `seed_runs`: each seed's run directory (runs.loop.Run of its plan);
    `offline`: the dataset of the run fine-tuned (None from scratch); `bar`: makes the progress
    bar from the environment steps so far; `sources`: the workdir each seed fine-tunes from
    (`online.init_from`, checked: runs.online.check_init_from; None from scratch)."""
    first = plans[0]
    self.plans, self.model, self.online = plans, first.learn.model, first.online
    self.fine_tune = sources is not None
    keep_plans = first.learn.losses.act_target == 'planned'
    self.seats = [Seat(run, p.online, self.model, offline, i, keep_plans)
                  for i, (p, run) in enumerate(zip(plans, seed_runs))]
    self.counters = dict(env_steps=0, updates=0, episodes=0, train_seconds=0.0,
                         pretrain_updates=0)
    states = self._restore()
    if states is None and self.fine_tune:
      states = [checkpointing.restore_latest(checkpointing.checkpoint_manager(source),
                                             checkpointing.abstract_state(first.learn))
                for source in sources]
    elif states is None:  # From scratch; observation statistics come with the seed data.
      states = [create_train_state(first.learn, jax.random.key(seat.online.seed))
                for seat in self.seats]
      self.counters['normalized'] = not self.model.normalize_obs
    self.groups = SeedGroups(len(self.seats), first.loop.seed_devices)
    self.states = self.groups.split(stack_states(states))  # One stack per device.
    self._views = None
    # Fine-tuning, and runs with demonstrations (MoDem's seeding phase acts with the policy
    # pretrained on them, plus the executed-action noise), learn from the start.
    self.learn_start = 0 if self.fine_tune or self.online.demos else self.online.seed_steps
    self.acting_schedule = ActingSchedule(self.online, self.learn_start)  # Annealed.
    self.per_call = self.online.updates_per_call
    self.update = {n: make_seeds_update(first.learn, n, self.per_call)
                   for n in set(self.groups.sizes)}
    self.keys = self.groups.split(jnp.stack([seat.update_key for seat in self.seats]))
    # Each seed's update key at an update count: one jitted call, not one per seed.
    self._fold = jax.jit(jax.vmap(jax.random.fold_in, in_axes=(0, None)))
    # The acting policy's settings: the evaluation's, with the acting planner's.
    act = first.eval.act
    self.acting = dataclasses.replace(act, plan=self.online.acting_plan(act.plan))
    self.metrics, self.last = [], None  # `last`: (mode, seconds, WaveRecords) of the last wave.
    self.runs = SeatRuns(self.seats)
    self.bar = bar(self.counters['env_steps'])

  def _restore(self):
    """Each seed's TrainState at the newest step that every seed has intact, with its buffer
    file, and seed 0's counters; None without a checkpoint. Newer steps (damaged, without a
    buffer file, or not saved by every seed: a run killed between two seeds' saves) are skipped
    with a warning (`runs.Run.restore`)."""
    if not any(seat.run.manager.all_steps() for seat in self.seats):
      for seat in self.seats:  # From scratch: rows an earlier attempt logged go.
        seat.run.restore()
      return None
    allowed = set.intersection(*(set(seat.run.manager.all_steps()) for seat in self.seats))

    def usable(seat):
      def reason(step):
        if step not in allowed:
          return 'not checkpointed by every seed of this run'
        path = buffer_path(seat.run.workdir, step)
        return None if os.path.exists(path) else f'no {path}'
      return reason
    while True:
      states = [seat.run.restore(usable(seat)) for seat in self.seats]
      steps = {seat.run.step for seat in self.seats}
      if len(steps) == 1:
        break
      allowed = {s for s in allowed if s <= min(steps)}  # One seed fell back further.
    for seat in self.seats:
      counters = seat.buffer.load(buffer_path(seat.run.workdir, seat.run.step))
      if seat.index == 0:  # Buffers saved before demonstrations existed lack the counter.
        self.counters = dict(counters, pretrain_updates=counters.get('pretrain_updates', 0))
    return states

  @property
  def progress(self) -> int:
    return self.counters['env_steps']

  def learning(self) -> bool:
    return self.counters['env_steps'] >= self.learn_start

  def views(self):
    """Each seed's EMA parameters (one jitted slicing per change of the state)."""
    if self._views is None:
      self._views = self.groups.per_seed([g.ema_params for g in self.states])
    return self._views

  def group_ema_params(self):
    """Each device's stacked EMA parameters (the acting policy's, `WavePolicy`)."""
    return [g.ema_params for g in self.states]

  def seed_metrics(self) -> Dict[str, np.ndarray]:
    """The last update's metrics, [num_seeds] numpy per name ({} before the first update)."""
    return self.groups.join_host(self.metrics) if self.metrics else {}

  def catch_up(self, ahead: int = 0) -> None:
    """Updates until floor(update_ratio x (environment steps + `ahead`)) have been made.

    `ahead`: steps the environments are about to take. The updates they call for are dispatched
    before the environments step, so that XLA computes them (asynchronously, on its own threads)
    while MuJoCo steps: the same updates in the same order as when they wait for the steps (the
    buffers change only between waves), the environment loop off the critical path.

    From scratch, the first call sets the encoder's observation statistics from the seed
    episodes and demonstrations (`config.model.normalize_obs`) before any update, then makes
    the `online.demo_pretrain_updates` updates on the demonstrations alone (MoDem's BC
    pretraining; not counted in the update ratio).
    """
    c, o = self.counters, self.online
    if not c.get('normalized', True):  # Counters; fine-tuning starts normalized (no key).
      params = stack_states([set_obs_normalization(
          p, np.concatenate([ep['obs'] for ep in s.buffer.episodes + s.buffer.demos]),
          self.model.obs_mask_constant)
                             for s, p in zip(self.seats, self.groups.per_seed(
                                 [g.params for g in self.states]))])
      self.states = [state.replace(  # Copies: the update donates both trees.
          params=p, ema_params=jax.tree_util.tree_map(jnp.copy, p))
                     for state, p in zip(self.states, self.groups.split(params))]
      c['normalized'], self._views = True, None
    if o.demos and c['pretrain_updates'] < o.demo_pretrain_updates:
      self._updates(o.demo_pretrain_updates, 'pretrain_updates', share=1.0)
    steps = c['env_steps'] + ahead
    self._updates(int(o.update_ratio * steps), 'updates', share=self.online.demo_share(steps))

  def _updates(self, target: int, counter: str, share: float) -> None:
    """Updates until counters[counter] reaches `target`, `online.updates_per_call` per jitted
    call, a `share` of each batch from the demonstrations (`Buffer.sample`)."""
    c, batch, n = self.counters, self.plans[0].loop.batch_size, self.per_call
    while c[counter] + n <= target:
      per_seat = [seat.buffer.sample(batch, n, share) for seat in self.seats]
      shape = (n, batch) if n > 1 else (batch,)
      windows = {k: np.stack([w[k].reshape(shape + w[k].shape[1:]) for w in per_seat])
                 for k in per_seat[0]}
      step = c['updates'] + c['pretrain_updates']  # One key per update made.
      # One call per device, dispatched without waiting: the devices update at the same time.
      out = [self.update[n](state, part, self._fold(keys, step)) for n, state, part, keys in
             zip(self.groups.sizes, self.states, self.groups.split_host(windows), self.keys)]
      self.states, self.metrics = [o[0] for o in out], [o[1] for o in out]
      c[counter] += n
      self._views = None

  def advance(self) -> None:
    """One wave: its episodes into the buffers, its acting and update time into the counters."""
    start = time.perf_counter()
    schedule = self.schedule()
    records = self.wave(schedule)
    for seat, record in zip(self.seats, records):
      seat.buffer.add(record.episodes)
    seconds = time.perf_counter() - start
    self.counters['train_seconds'] += seconds
    self.last = (schedule.mode, seconds, records)

  def acting_mode(self) -> str:
    """Who acts in the next wave: 'random' (seed waves from scratch), 'actor' (seed waves with
    demonstrations and `online.demo_seed_actor`: the actor prior pretrained on them), else
    `online.act_mode` ('plan' or 'actor')."""
    o = self.online
    if not self.learning():
      return 'random'
    if o.demos and o.demo_seed_actor and self.counters['env_steps'] < o.seed_steps:
      return 'actor'
    return o.act_mode

  def schedule(self) -> WaveSchedule:
    """What the next wave acts with: who acts, the executed noise and the planner's intrinsic
    term at the environment steps so far."""
    steps = self.counters['env_steps']
    return WaveSchedule(self.acting_mode(),
                        self.acting_schedule.executed_noise(steps),
                        self.acting_schedule.intrinsic(steps))

  def wave(self, schedule: WaveSchedule) -> list:
    """One episode per environment of every seed, in lockstep, as `schedule` says; returns each
    seat's `WaveRecord`."""
    o, first = self.online, self.counters['episodes']
    planner = schedule.mode != 'random'
    if planner:
      self.catch_up()
    acting = [SeatWave(self, seat, first, schedule) for seat in self.seats]
    policy = WavePolicy(self, schedule, acting) if planner else None
    t, none = 0, [None] * len(acting)
    while acting[0].active.any():  # The seeds' episodes have the same lengths.
      actions, infos, sequences = (policy([w.obs for w in acting], t, acting[0].active)
                                   if planner else (none, none, none))
      if planner:  # The updates these steps call for, dispatched to run while they step.
        self.catch_up(ahead=acting[0].upcoming())
      steps = [w.step(a, i, s) for w, a, i, s in zip(acting, actions, infos, sequences)]
      self.counters['env_steps'] += steps[0]
      self.bar.update(steps[0])
      t += 1
      if planner:
        self.catch_up()
        policy.refresh()
    self.counters['episodes'] += o.num_envs
    return [w.finish() for w in acting]

  def checkpoint(self) -> None:
    """Each seed's buffer file, then its orbax step (environment steps); older buffer files
    go."""
    step = self.counters['env_steps']
    states = self.groups.per_seed(self.states)
    for seat, state in zip(self.seats, states):
      workdir, manager = seat.run.workdir, seat.run.manager
      seat.buffer.save(buffer_path(workdir, step), self.counters)
      seat.run.save(state, step, self.counters['train_seconds'])
      keep = {f'buffer_{s}.npz' for s in manager.all_steps()}
      for name in os.listdir(os.path.join(workdir, BUFFER_DIR)):
        if name.startswith('buffer_') and name not in keep:
          os.remove(os.path.join(workdir, BUFFER_DIR, name))

  def eval_params(self):
    """Each seed's EMA parameters (`_SeatRuns.periodic_eval`)."""
    return self.views()

  def log(self, before: int) -> None:
    mode, seconds, records = self.last
    for seat, record in zip(self.seats, records):
      seat.log(self, before, record, mode, seconds)
    self.bar.set_postfix(updates=self.counters['updates'], success=np.mean(
        [e['success'].any() for record in records for e in record.episodes]))
