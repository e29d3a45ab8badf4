"""Policies for the environment loop: the planner, the actor prior, the proposal alone, and MPPI
on the learned model (config.mppi; the TD-MPC2-style baseline).

Each is one jitted function of (params, obs, key, t) that encodes the observation and acts, so a
decision costs one dispatch; the per-step key is fold_in(key, t) inside jit. `make_policy` wraps
one in the `policy(obs) -> action` interface of `ld_mpc_jax.evaluation.evaluate`.
"""

from typing import Callable, Tuple

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from ld_mpc_jax.models import build_networks
from ld_mpc_jax.planner import make_plan, make_propose

MODES = ('plan', 'actor', 'proposal', 'mppi')


def make_act(config: ml_collections.ConfigDict, mode: str = 'plan') -> Callable:
  """Returns jitted act(params, obs [obs_dim], key, t [], prev) -> (action [A], sequence [H, A]).

  `prev` is the previous decision's sequence (or None at the start of an episode); only the
  planner with `plan.warm_start_steps` > 0 and MPPI (its Gaussian mean) use it. `sequence` is what to pass as the next `prev`.
  """
  nets = build_networks(config)
  encode = lambda params, obs: nets.encoder.apply({'params': params['encoder']}, obs)
  if mode == 'plan':
    plan = make_plan(config)
    def act(params, obs, key, prev):
      out = plan(params, encode(params, obs), key, prev)
      return out.action, out.sequence
  elif mode == 'actor':
    def act(params, obs, key, prev):
      a = nets.actor.apply({'params': params['actor']}, encode(params, obs))
      return a, jnp.broadcast_to(a, (config.horizon,) + a.shape)
  elif mode == 'mppi':
    from ld_mpc_jax.mppi import make_ldmpc_mppi
    mppi_plan = make_ldmpc_mppi(config)
    def act(params, obs, key, prev):
      out = mppi_plan(params, encode(params, obs), key, prev)
      return out.action, out.mean
  elif mode == 'proposal':
    propose = make_propose(config, nets)
    def act(params, obs, key, prev):
      seq = jnp.clip(propose(params, encode(params, obs), key, 1)[0], -1.0, 1.0)
      if seq.shape[0] == 1:  # Single-step proposal kinds: hold the one action.
        seq = jnp.repeat(seq, config.horizon, axis=0)
      return seq[0], seq
  else:
    raise ValueError(f'mode must be one of {MODES}, got {mode!r}')
  return jax.jit(lambda params, obs, key, t, prev: act(params, obs, jax.random.fold_in(key, t),
                                                       prev))


def make_policy(config: ml_collections.ConfigDict, params, mode: str = 'plan', seed: int = 0
                ) -> Tuple[Callable[[np.ndarray], np.ndarray], Callable[[], None]]:
  """(policy, reset) for the evaluation loop: policy(obs [obs_dim]) -> action [A].

  Host state is a decision counter (it keeps counting across episodes, so no two decisions
  share a key) and, with warm starts, the previous sequence, which stays on the device.
  `reset()` forgets the previous sequence at the start of an episode.
  """
  act = make_act(config, mode)
  key = jax.random.key(seed)
  warm = (mode == 'plan' and config.plan.warm_start_steps > 0) or mode == 'mppi'
  state = {'t': 0, 'prev': None}

  def policy(obs: np.ndarray) -> np.ndarray:
    action, sequence = act(params, jnp.asarray(obs, jnp.float32), key, state['t'], state['prev'])
    state['t'] += 1
    if warm:
      state['prev'] = sequence
    return np.asarray(action)

  def reset() -> None:
    state['prev'] = None

  return policy, reset
