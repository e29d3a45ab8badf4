"""An online run's job (`runs.loop.Job`): one wave of episodes and its updates per advance.

`OnlineJob` holds one `Seat` per training seed (ld_mpc_jax.online.seats), the `Learner` with
their stacked TrainStates (ld_mpc_jax.online.learner), the environment-step counters and the
acting schedule; `runs.online.train_online` builds it and drives it with `runs.loop`. Each wave
(`seats.run_wave`) acts with a `WaveSchedule` fixed at its start and asks the learner for the
updates its steps call for; the job's counters change after the wave.
"""

import dataclasses
import os
import time
from typing import Any, Callable, Dict, Optional, Sequence

import jax
import numpy as np

from ld_mpc_jax import data
from ld_mpc_jax.data.online_buffer import BUFFER_DIR, buffer_path
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import create_train_state
from ld_mpc_jax.online.learner import COUNTERS, Learner
from ld_mpc_jax.online.schedule import ActingSchedule
from ld_mpc_jax.online.seats import Seat, WaveSchedule, run_wave


class OnlineJob:
  """An online run as a `runs.loop.Job`: each advance is one wave of episodes and its updates.

  Holds one `Seat` per training seed (run directory, buffer, environments), the `Learner`
  (every seed's TrainState stacked on a leading seed axis; `train.num_seeds`) and the counters
  of environment steps (the job's progress), episodes and seconds, which the seeds share: they
  act in lockstep, each on its own episodes, and each seed's run is the one it would make alone.
  """

  def __init__(self, plans: Sequence, seed_runs: Sequence, offline: Optional[data.Dataset],
               bar: Callable[[int], Any], log_wave: Callable,
               sources: Optional[Sequence[str]] = None):
    """`plans`: each training seed's SeedPlan (runs.seed_plan.seed_plans), which differ in their
    seeds (and sources) only; `seed_runs`: each seed's run directory (runs.loop.Run of its plan);
    `offline`: the dataset of the run fine-tuned (None from scratch); `bar`: makes the progress
    bar from the environment steps so far; `log_wave`: writes down a seed's wave
    (runs.online_report.log_wave: online.csv, losses.csv); `sources`: the workdir each seed
    fine-tunes from (`online.init_from`, checked: runs.online.check_init_from; None from
    scratch)."""
    first = plans[0]
    self.plans, self.model, self.online = plans, first.learn.model, first.online
    self.log_wave = log_wave
    self.fine_tune = sources is not None
    keep_plans = first.learn.losses.act_target == 'planned'
    self.seats = [Seat(run, p.online, self.model, offline, i, keep_plans)
                  for i, (p, run) in enumerate(zip(plans, seed_runs))]
    counters = dict(env_steps=0, updates=0, episodes=0, train_seconds=0.0, pretrain_updates=0)
    states, saved = self._restore()
    counters.update(saved)
    if states is None and self.fine_tune:
      states = [checkpointing.restore_latest(checkpointing.checkpoint_manager(source),
                                             checkpointing.abstract_state(first.learn))
                for source in sources]
    elif states is None:  # From scratch; observation statistics come with the seed data.
      states = [create_train_state(first.learn, jax.random.key(seat.online.seed))
                for seat in self.seats]
      counters['normalized'] = not self.model.normalize_obs
    self.learner = Learner(first.learn, self.online, first.loop.batch_size,
                           first.loop.seed_devices, states, [s.buffer for s in self.seats],
                           [s.update_key for s in self.seats], counters)
    self.steps = {k: v for k, v in counters.items() if k not in COUNTERS}
    # Fine-tuning, and runs with demonstrations (MoDem's seeding phase acts with the policy
    # pretrained on them, plus the executed-action noise), learn from the start.
    self.learn_start = 0 if self.fine_tune or self.online.demos else self.online.seed_steps
    self.acting_schedule = ActingSchedule(self.online, self.learn_start)  # Annealed.
    # The acting policy's settings: the evaluation's, with the acting planner's.
    act = first.eval.act
    self.acting = dataclasses.replace(act, plan=self.online.acting_plan(act.plan))
    self.last = None  # (mode, seconds, WaveRecords) of the last wave.
    self.bar = bar(self.steps['env_steps'])

  @property
  def counters(self) -> Dict[str, Any]:
    """The run's counters (a copy): environment steps, episodes, seconds, and the learner's."""
    return {**self.steps, **self.learner.counters}

  def _restore(self):
    """(each seed's TrainState at the newest step that every seed has intact, with its buffer
    file, and seed 0's counters), or (None, {}) without a checkpoint. Newer steps (damaged,
    without a buffer file, or not saved by every seed: a run killed between two seeds' saves)
    are skipped with a warning (`runs.Run.restore`)."""
    if not any(seat.run.manager.all_steps() for seat in self.seats):
      for seat in self.seats:  # From scratch: rows an earlier attempt logged go.
        seat.run.restore()
      return None, {}
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
    saved = [seat.buffer.load(buffer_path(seat.run.workdir, seat.run.step))
             for seat in self.seats]
    # Seed 0's; buffers saved before demonstrations existed lack the pretraining counter.
    return states, dict(saved[0], pretrain_updates=saved[0].get('pretrain_updates', 0))

  @property
  def progress(self) -> int:
    return self.steps['env_steps']

  def advance(self) -> None:
    """One wave (`seats.run_wave`): its episodes into the buffers, then its steps, episodes and
    time into the counters."""
    start = time.perf_counter()
    schedule = self.schedule()
    records, steps = run_wave(self.seats, schedule, self.acting, self.online,
                              self.model.action_dim, self.steps, self.learner, self.bar,
                              data_parallel=self.plans[0].eval.eval.data_parallel)
    for seat, record in zip(self.seats, records):
      seat.buffer.add(record.episodes)
    seconds = time.perf_counter() - start
    self.steps = dict(self.steps, env_steps=self.steps['env_steps'] + steps,
                      episodes=self.steps['episodes'] + self.online.num_envs,
                      train_seconds=self.steps['train_seconds'] + seconds)
    self.last = (schedule.mode, seconds, records)

  def acting_mode(self) -> str:
    """Who acts in the next wave: 'random' (seed waves from scratch), 'actor' (seed waves with
    demonstrations and `online.demo_seed_actor`: the actor prior pretrained on them), else
    `online.act_mode` ('plan' or 'actor')."""
    o = self.online
    if self.steps['env_steps'] < self.learn_start:
      return 'random'
    if o.demos and o.demo_seed_actor and self.steps['env_steps'] < o.seed_steps:
      return 'actor'
    return o.act_mode

  def schedule(self) -> WaveSchedule:
    """What the next wave acts with: who acts, the executed noise and the planner's intrinsic
    term at the environment steps so far."""
    steps = self.steps['env_steps']
    return WaveSchedule(self.acting_mode(),
                        self.acting_schedule.executed_noise(steps),
                        self.acting_schedule.intrinsic(steps))

  def checkpoint(self) -> None:
    """Each seed's buffer file, then its orbax step (environment steps); older buffer files
    go."""
    step, counters = self.steps['env_steps'], self.counters
    for seat, state in zip(self.seats, self.learner.per_seed_states()):
      workdir, manager = seat.run.workdir, seat.run.manager
      seat.buffer.save(buffer_path(workdir, step), counters)
      seat.run.save(state, step, counters['train_seconds'])
      keep = {f'buffer_{s}.npz' for s in manager.all_steps()}
      for name in os.listdir(os.path.join(workdir, BUFFER_DIR)):
        if name.startswith('buffer_') and name not in keep:
          os.remove(os.path.join(workdir, BUFFER_DIR, name))

  def eval_params(self):
    """Each seed's EMA parameters, in the seats' order."""
    return self.learner.views()

  def log(self, before: int) -> None:
    """Each seed's wave written down (`log_wave`), the progress bar's figures."""
    mode, seconds, records = self.last
    for seat, record in zip(self.seats, records):
      self.log_wave(self, seat, before, record, mode, seconds)
    self.bar.set_postfix(updates=self.counters['updates'], success=np.mean(
        [e['success'].any() for record in records for e in record.episodes]))
