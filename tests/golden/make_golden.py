"""Writes the behaviour fixtures that tests/test_golden.py checks (run once, before a refactor).

  python -m tests.golden.make_golden

- door_open_smoke/: a `door_open.py:smoke` training workdir (config.json and one orbax
  checkpoint of a freshly initialised TrainState): a checkpoint saved by the code of that
  commit, which later code must still load.
- plans.npz: for the smoke checkpoint's EMA parameters and for `door_open.py:cpu` parameters
  initialised from key(0), the actions, sequences and plan info of the planner, the actor prior
  and the proposal alone on fixed observations and keys.
"""

import os
import shutil

import jax
import numpy as np
import orbax.checkpoint as ocp

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.plan import agent
from ld_mpc_jax.learn import checkpointing, train_state
from ld_mpc_jax.plan.modes import ActSettings

HERE = os.path.dirname(os.path.abspath(__file__))
SMOKE_DIR = os.path.join(HERE, 'door_open_smoke')
PLANS = os.path.join(HERE, 'plans.npz')
MODES = ('plan', 'actor', 'proposal')
NUM_OBS = 3


def observations(config) -> np.ndarray:
  """[NUM_OBS, obs_dim] fixed observations (a seeded normal draw)."""
  return np.random.default_rng(0).normal(size=(NUM_OBS, config.obs_dim)).astype(np.float32)


def decisions(config, params) -> dict:
  """{mode_field: array} of every mode's decisions on `observations` with key(7), t = i."""
  out = {}
  obs = observations(config)
  for mode in MODES:
    act = agent.make_act(ActSettings.from_config(config), mode)
    rows = [act(params, obs[i], jax.random.key(7), i, None) for i in range(NUM_OBS)]
    for j, field in enumerate(('action', 'sequence', 'info')):
      out[f'{mode}_{field}'] = np.stack([np.asarray(r[j]) for r in rows])
  return out


def main() -> None:
  smoke = door_open.get_config('smoke')
  shutil.rmtree(SMOKE_DIR, ignore_errors=True)
  os.makedirs(SMOKE_DIR)
  checkpointing.save_config(smoke, SMOKE_DIR)
  state = train_state.create_train_state(train_state.LearnSettings.from_config(smoke),
                                         jax.random.key(0))
  manager = checkpointing.checkpoint_manager(SMOKE_DIR)
  manager.save(0, args=ocp.args.StandardSave(state))
  manager.wait_until_finished()
  _, params, _ = checkpointing.load_for_evaluation(SMOKE_DIR)
  arrays = {f'smoke_{k}': v for k, v in decisions(smoke, params).items()}
  cpu = door_open.get_config('cpu')
  cpu_learn = train_state.LearnSettings.from_config(cpu)
  cpu_params = train_state.create_train_state(cpu_learn, jax.random.key(0)).ema_params
  arrays.update({f'cpu_{k}': v for k, v in decisions(cpu, cpu_params).items()})
  np.savez(PLANS, **arrays)
  print(f'wrote {SMOKE_DIR} and {PLANS}')


if __name__ == '__main__':
  main()
