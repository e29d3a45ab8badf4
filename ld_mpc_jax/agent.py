"""Policies for the environment loop: the planner, the actor prior, the proposal alone.

Each is one jitted function of (params, obs, key, t) that encodes the observation and acts, so a
decision costs one dispatch; the per-step key is fold_in(key, t) inside jit. `make_policy` wraps
one in the `policy(obs) -> action` interface of `ld_mpc_jax.evaluation.evaluate`.
"""

from typing import Callable

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from ld_mpc_jax.models import build_networks
from ld_mpc_jax.planner import make_plan, make_propose

MODES = ('plan', 'actor', 'proposal')


def make_act(config: ml_collections.ConfigDict, mode: str = 'plan') -> Callable:
  """Returns jitted act(params, obs [obs_dim], key, t []) -> action [A] in [-1, 1]."""
  nets = build_networks(config)
  encode = lambda params, obs: nets.encoder.apply({'params': params['encoder']}, obs)
  if mode == 'plan':
    plan = make_plan(config)
    act = lambda params, obs, key: plan(params, encode(params, obs), key).action
  elif mode == 'actor':
    act = lambda params, obs, key: nets.actor.apply({'params': params['actor']},
                                                    encode(params, obs))
  elif mode == 'proposal':
    propose = make_propose(config, nets)
    act = lambda params, obs, key: jnp.clip(propose(params, encode(params, obs), key, 1)[0, 0],
                                            -1.0, 1.0)
  else:
    raise ValueError(f'mode must be one of {MODES}, got {mode!r}')
  return jax.jit(lambda params, obs, key, t: act(params, obs, jax.random.fold_in(key, t)))


def make_policy(config: ml_collections.ConfigDict, params, mode: str = 'plan',
                seed: int = 0) -> Callable[[np.ndarray], np.ndarray]:
  """policy(obs [obs_dim]) -> action [A] for the evaluation loop.

  The decision counter is the only host state; it keeps counting across episodes so that no
  two decisions share a key.
  """
  act = make_act(config, mode)
  key = jax.random.key(seed)
  counter = [0]

  def policy(obs: np.ndarray) -> np.ndarray:
    a = act(params, jnp.asarray(obs, jnp.float32), key, counter[0])
    counter[0] += 1
    return np.asarray(a)

  return policy
