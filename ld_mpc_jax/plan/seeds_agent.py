"""S agents acting in lockstep, one per training seed (`train.num_seeds`; ld_mpc_jax.runs.online):
a policy mode of ld_mpc_jax.plan.agent vmapped over a leading seed axis of the parameters, each
agent on its own environments with its own key schedule."""

from typing import Callable, Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.ops.seed_groups import SeedGroups
from ld_mpc_jax.plan.agent import (NO_PLAN_INFO, ActSettings, episode_keys, float32,
                                   float32_tree, make_act_fn, uses_prev)
from ld_mpc_jax.plan.modes import carried_sequence

_SEEDS_ACTS = {}  # One jitted function per setting, compiled once per process.


def make_seeds_act(settings: ActSettings, mode: str = 'plan') -> Callable:
  """Returns jitted act(params [S, ...], obs [S, obs_dim], keys [S], t [], prev, noise [],
  intrinsic=None) -> (actions [S, A], carries, infos [S, 6]): `make_act` vmapped over a leading
  seed axis of the parameters (S agents of `train.num_seeds`, each on its own environment and
  key); the noise and the intrinsic term are the same for every agent."""
  act = make_act_fn(settings, mode)
  one = lambda params, obs, key, t, prev, noise, intrinsic: act(
      params, obs, jax.random.fold_in(key, t), prev, noise, intrinsic)
  jitted = jax.jit(jax.vmap(one, in_axes=(0, 0, 0, None, 0, None, None)))
  return lambda params, obs, keys, t, prev, noise=0.0, intrinsic=None: jitted(
      params, obs, keys, t, prev, float32(noise), float32_tree(intrinsic))


class SeedsAgentPolicy:
  """S agents acting on N environments each in lockstep: for each environment and decision, one
  jitted call per device for the agents on it (`make_seeds_act` on a group's stacked
  parameters, `ops.seed_groups`; all calls of a decision are dispatched before any is waited
  for, so the devices plan at the same time); each agent's episodes keep the key schedule of
  `agent.BatchAgentPolicy` with its own seed, so an agent acts as it would alone (to float
  tolerance: the vmapped plan may round differently). `keep_sequences`: as BatchAgentPolicy's
  (`last_sequences` [S, N, H, A])."""

  def __init__(self, settings: ActSettings, params, mode: str, seeds: Sequence[int],
               groups: Optional[SeedGroups] = None, action_noise: float = 0.0, intrinsic=None,
               keep_sequences: bool = False):
    """params: the agents' parameters stacked [S, ...], or one stack per group of `groups`."""
    self.seeds = list(seeds)
    self.groups = groups or SeedGroups(len(self.seeds))
    self.set_params(params)
    self.warm = uses_prev(settings.plan, mode)
    self.action_dim = settings.model.action_dim
    key = (settings, mode)
    if key not in _SEEDS_ACTS:
      _SEEDS_ACTS[key] = make_seeds_act(settings, mode)
    self.act = _SEEDS_ACTS[key]
    self.keys = self.prev = None
    self.action_noise, self.intrinsic = action_noise, intrinsic  # As agent.BatchAgentPolicy's.
    self.last_info = None  # [S, N, 6] float32 of the last decision.
    self.sequence_shape = (settings.model.horizon, settings.model.action_dim)
    self.sequence_of = (lambda carry: carried_sequence(settings.plan, carry)) if (
        keep_sequences) else None
    self.last_sequences = None

  def set_params(self, params) -> None:
    self.params = self.prepare(params)

  def prepare(self, params):
    """`params` as `decide` takes them: one stack per group of `groups`."""
    return list(params) if isinstance(params, (list, tuple)) else self.groups.split(params)

  def start(self, episodes) -> None:
    """episodes[s]: agent s's episodes of the wave (goals.Episode, one per environment)."""
    keys = jnp.stack([episode_keys(seed, [ep.reset_seed for ep in eps])
                      for seed, eps in zip(self.seeds, episodes)])  # [S, N]
    # Each group's keys per environment, sliced once here: slicing in the loop would be an
    # eager operation that waits behind the updates dispatched to the device.
    self.keys = [[k[:, i] for i in range(k.shape[1])] for k in self.groups.split(keys)]
    self.prev = None

  def __call__(self, obs: np.ndarray, t: int, active: np.ndarray) -> np.ndarray:
    """obs [S, N, obs_dim], active [N] -> actions [S, N, A] (zeros where inactive)."""
    actions, self.last_info, self.last_sequences, self.prev = self.decide(
        self.params, obs, t, active, self.prev)
    return actions

  def decide(self, params, obs: np.ndarray, t: int, active: np.ndarray, prev):
    """One decision of the wave `start` began, writing nothing on the policy: (actions
    [S, N, A], infos [S, N, 7], the planner's chosen sequences [S, N, H, A] or None, the
    warm-start carry for the next decision). `params` as `prepare` gives them; `prev`: None
    at a wave's first decision."""
    s, n = obs.shape[:2]
    prev = ([[None] * n for _ in self.groups.bounds] if prev is None
            else [list(p) for p in prev])
    actions = np.zeros((s, n, self.action_dim), np.float32)
    infos = np.tile(np.asarray(NO_PLAN_INFO, np.float32), (s, n, 1))
    pending = []  # Every call of this decision dispatched first, then read.
    for i in np.flatnonzero(active):
      for g, (a, b) in enumerate(self.groups.bounds):
        action, carry, info = self.act(params[g], obs[a:b, i].astype(np.float32),
                                       self.keys[g][i], t, prev[g][i],
                                       self.action_noise, self.intrinsic)
        if self.warm:
          prev[g][i] = carry
        pending.append((a, b, i, action, info, carry))
    sequences = (np.zeros((s, n) + self.sequence_shape, np.float32)
                 if self.sequence_of is not None else None)
    for a, b, i, action, info, carry in pending:
      actions[a:b, i], infos[a:b, i] = np.asarray(action), np.asarray(info)
      if sequences is not None:
        sequences[a:b, i] = np.asarray(self.sequence_of(carry))
    return actions, infos, sequences, prev
