"""End to end, data parallel on 2 devices (ld_mpc_jax.ops.sharding): the update gives the same loss
and parameters as one device, the batched planner the same actions.

The 2-device case runs in a subprocess with XLA_FLAGS=--xla_force_host_platform_device_count=2:
this pytest process initialised JAX with a single CPU device.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# Two updates (dropout on) single-device and data-parallel from the same state, batch and keys.
_SCRIPT = r'''
import json
import jax
import numpy as np
from ld_mpc_jax.configs import door_open
from ld_mpc_jax.ops import sharding
from ld_mpc_jax.learn.train_state import LearnSettings, create_train_state, make_update

c = door_open.get_config('smoke')
c.critic.latent_rollout = False  # A third less to compile; the sharding does not depend on it.
h, b = c.horizon, c.train.batch_size
rng = np.random.default_rng(0)
batch = dict(obs=rng.normal(size=(b, h + 2, 39)).astype(np.float32),
             action=rng.uniform(-1, 1, (b, h + 1, 4)).astype(np.float32),
             reward=rng.uniform(0, 10, (b, h + 1)).astype(np.float32))
learn = LearnSettings.from_config(c)
fresh = lambda: create_train_state(learn, jax.random.key(0), batch['obs'].reshape(-1, 39))
single = make_update(learn)
state1 = fresh()
for i in range(2):
  state1, m1 = single(state1, batch, jax.random.key(i))
c.train.data_parallel = True
mesh = sharding.make_mesh()
parallel = make_update(LearnSettings.from_config(c))  # The mesh: all devices.
state2 = sharding.replicate(fresh(), mesh)
sharded = sharding.shard_batch(batch, mesh)
compiled = parallel.lower(state2, sharded, jax.random.key(0)).compile()
for i in range(2):  # The compiled executable: compiled once, its program inspected below.
  state2, m2 = compiled(state2, sharding.shard_batch(batch, mesh), jax.random.key(i))
leaves1 = jax.tree_util.tree_leaves(jax.device_get(state1.params))
leaves2 = jax.tree_util.tree_leaves(jax.device_get(state2.params))
print(json.dumps(dict(
    devices=jax.device_count(), mesh_size=mesh.size,
    loss=[float(m1['loss']), float(m2['loss'])],
    grad_norm=[float(m1['grad_norm']), float(m2['grad_norm'])],
    max_param_diff=max(float(np.abs(x - y).max()) for x, y in zip(leaves1, leaves2)),
    max_param_change=max(float(np.abs(x - y).max()) for x, y in zip(
        leaves1, jax.tree_util.tree_leaves(jax.device_get(fresh().params)))),
    batch_shards=[list(s.data.shape) for s in sharded['obs'].addressable_shards],
    params_replicated=all(x.sharding.is_fully_replicated and len(x.sharding.device_set) == 2
                          for x in jax.tree_util.tree_leaves(state2.params)),
    all_reduce='all-reduce' in compiled.as_text(), step=int(state2.step))))
'''


@pytest.mark.long
def test_two_device_update_matches_one_device():
  flags = os.environ.get('XLA_FLAGS', '') + ' --xla_force_host_platform_device_count=2'
  env = dict(os.environ, XLA_FLAGS=flags.strip(),
             JAX_PLATFORMS='cpu', PYTHONPATH=REPO)
  done = subprocess.run([sys.executable, '-c', _SCRIPT], cwd=REPO, env=env,
                        capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  out = json.loads(done.stdout.strip().splitlines()[-1])
  assert out['devices'] == 2 and out['mesh_size'] == 2 and out['step'] == 2
  b, h = 8, 4  # The smoke preset's batch and horizon.
  assert out['batch_shards'] == [[b // 2, h + 2, 39]] * 2  # Half of the batch on each device.
  assert out['params_replicated']
  assert out['all_reduce']  # Gradients are summed across devices, not computed on one.
  np.testing.assert_allclose(out['loss'][1], out['loss'][0], rtol=1e-5)
  np.testing.assert_allclose(out['grad_norm'][1], out['grad_norm'][0], rtol=1e-4)
  assert out['max_param_change'] > 1e-4  # The updates moved the parameters ...
  assert out['max_param_diff'] < 1e-5  # ... and both moved them the same way.


# The batched planner for 3 environments (padded to 4 on the mesh), first decision and warm
# start, on one device and split over 2: the same actions.
_PLAN_SCRIPT = r'''
import json
import jax
import numpy as np
from ld_mpc_jax.configs import door_open
from ld_mpc_jax.plan import agent
from ld_mpc_jax.ops import sharding
from ld_mpc_jax.model.models import init_params
from ld_mpc_jax.plan.modes import ActSettings

c = door_open.get_config('smoke')
c.plan.warm_start_steps = 2  # The second decision starts from the first one's plan.
params = init_params(c, jax.random.key(0))
obs = np.random.default_rng(0).normal(size=(3, 39)).astype(np.float32)
keys = agent.episode_keys(0, [5, 6, 7])
active = np.array([True, True, False])
mesh = sharding.make_mesh()
out = {}
for name, m in (('one', None), ('two', mesh)):
  act = agent.make_batch_act(ActSettings.from_config(c), 'plan', chunk=1, mesh=m)
  p = params if m is None else sharding.replicate(params, m)
  a0, seq, _ = act(p, obs, keys, 0, None, active)
  a1, _, _ = act(p, obs, keys, 1, seq, active)
  cold, _, _ = act(p, obs, keys, 1, None, active)
  out[name] = [np.asarray(a0).tolist(), np.asarray(a1).tolist(), np.asarray(cold).tolist()]
  out[name + '_devices'] = len(seq.sharding.device_set)
# The evaluation's policy object on the mesh (chunk 0: one environment at a time per device).
policy = agent.BatchAgentPolicy(ActSettings.from_config(c), params, 'plan', chunk=0, mesh=mesh)
policy.keys = keys
out['policy'] = policy(obs, 0, active).tolist()
print(json.dumps(out))
'''


@pytest.mark.long
def test_two_device_batched_planner_gives_the_same_actions():
  flags = os.environ.get('XLA_FLAGS', '') + ' --xla_force_host_platform_device_count=2'
  env = dict(os.environ, XLA_FLAGS=flags.strip(), JAX_PLATFORMS='cpu', PYTHONPATH=REPO)
  done = subprocess.run([sys.executable, '-c', _PLAN_SCRIPT], cwd=REPO, env=env,
                        capture_output=True, text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  out = json.loads(done.stdout.strip().splitlines()[-1])
  assert out['one_devices'] == 1 and out['two_devices'] == 2
  one, two = np.asarray(out['one']), np.asarray(out['two'])
  assert one.shape == (3, 3, 4)
  np.testing.assert_allclose(two, one, atol=1e-5)
  np.testing.assert_allclose(out['policy'], one[0], atol=1e-5)
  assert np.abs(one[:, :2]).max() > 1e-3  # Active environments act ...
  assert np.all(one[:, 2] == 0.0)  # ... the finished one returns zeros.
  # The previous plans reach every device's share: the warm-started decision differs from a
  # cold one with the same key.
  assert np.abs(one[1, :2] - one[2, :2]).max() > 1e-4
