"""End to end: scripts/gpu/offline.sh trains two seeds (the second from the first's
compilation cache), compares selection on each, and packs runs that evaluate as trained."""

import json
import os
import subprocess
import sys
import tarfile

import jax
import numpy as np
import pytest

from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.learn.train_state import LearnSettings

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.long
def test_offline_script_trains_compares_and_packs_ema_only_runs(tmp_path):
  evals = tmp_path / 'evals.txt'
  evals.write_text('quick --variant=argmax: --baselines=actor --episodes=1 --seed=0\n')
  env = dict(os.environ, OUT=str(tmp_path / 'out'), RUNS=str(tmp_path / 'runs'),
             DATA=str(tmp_path / 'data'), PY=sys.executable, SEEDS='0 1',
             CONFIG='ld_mpc_jax/configs/door_open.py:smoke', SETTINGS='smk:door-open-v3:medium',
             EVAL_FILE=str(evals), EVAL_T='200', MUJOCO_GL=os.environ.get('MUJOCO_GL', 'osmesa'))
  done = subprocess.run(['bash', 'scripts/gpu/offline.sh'], cwd=ROOT, env=env,
                        capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
  assert 'first seeds compiled at' in done.stdout
  assert sorted(os.listdir(tmp_path / 'out')) == ['logs.tgz', 'smk_seed0.tgz', 'smk_seed1.tgz']
  with tarfile.open(tmp_path / 'out' / 'smk_seed1.tgz') as t:
    t.extractall(tmp_path / 'unpacked')
  packed = str(tmp_path / 'unpacked' / 'smk_seed1')
  config, ema, step = checkpointing.load_for_evaluation(packed)
  assert step == 4 and config.seed == 1 and config.task == 'door-open-v3'
  _, original, _ = checkpointing.load_for_evaluation(str(tmp_path / 'runs' / 'smk_seed1'))
  for a, b in zip(jax.tree.leaves(ema), jax.tree.leaves(original)):
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))  # Evaluates as trained.
  learn = LearnSettings.from_config(config)
  state = checkpointing.restore_latest(checkpointing.checkpoint_manager(packed),
                                       checkpointing.abstract_state(learn))
  assert all(not np.any(np.asarray(x)) for x in jax.tree.leaves(state.params))  # Zeroed.
  result = json.load(open(os.path.join(packed, 'selection_quick.json')))
  assert [r['policy'] for r in result['rows']] == ['plan[argmax]', 'actor']
  assert len(result['records']) == 2 and os.listdir(os.path.join(packed, 'evals'))
