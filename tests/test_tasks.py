"""Task conditioning (ld_mpc_jax.model.tasks): the embedding, binding, and the multi-task loss."""

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open, mt10
from ld_mpc_jax.model import models, tasks
from ld_mpc_jax.model.critics import Critics
from ld_mpc_jax.learn.losses import make_loss_fn
from ld_mpc_jax.plan.planner import make_plan
from ld_mpc_jax.model.settings import LossSettings, ModelSettings


@pytest.fixture(scope='module')
def mt_config():
  return mt10.get_config('smoke')


@pytest.fixture(scope='module')
def mt_params(mt_config):
  return models.init_params(mt_config, jax.random.key(0))


def test_single_task_configs_keep_their_parameter_tree():
  single = door_open.get_config('smoke')
  params = models.init_params(single, jax.random.key(0))
  assert 'task' not in params
  assert tasks.bind(params, 0) is params
  one = door_open.get_config('smoke')
  one.tasks = ('door-open-v3',)  # One task: no embedding either, the same values.
  chex.assert_trees_all_equal(models.init_params(one, jax.random.key(0)), params)
  assert (not tasks.Tasks.from_config(one).multitask
          and tasks.Tasks.from_config(single).names == ('door-open-v3',))


def test_bound_parameters_are_a_single_task_tree(mt_config, mt_params):
  single = models.init_params(door_open.get_config('smoke'), jax.random.key(0))
  bound = tasks.bind(mt_params, 3)
  chex.assert_trees_all_equal_shapes(bound, single)
  assert set(mt_params['task']['proj']) == {'encoder', 'proposal', 'dynamics', 'objective',
                                            'actor', 'critics'}
  assert mt_params['task']['embedding'].shape == (10, mt_config.model.task_dim)
  # Only the input layers' biases move.
  flat_a = jax.tree_util.tree_leaves_with_path(bound)
  flat_b = dict(jax.tree_util.tree_leaves_with_path(
      {k: v for k, v in mt_params.items() if k != 'task'}))
  changed = [jax.tree_util.keystr(p) for p, v in flat_a if not np.array_equal(v, flat_b[p])]
  assert len(changed) == 7 and all(c.endswith("['bias']") for c in changed), changed


def test_embedding_has_at_most_unit_norm(mt_params):
  norms = [float(jnp.linalg.norm(tasks.embed(mt_params, k))) for k in range(10)]
  assert max(norms) <= 1.0 + 1e-6 and min(norms) > 0.99  # N(0, 1) rows of 8: clipped to 1.
  small = dict(mt_params, task=dict(mt_params['task'],
                                    embedding=mt_params['task']['embedding'] * 1e-3))
  np.testing.assert_allclose(tasks.embed(small, 2), small['task']['embedding'][2], rtol=1e-6)


def test_binding_equals_concatenating_the_embedding(mt_params):
  """TD-MPC2's Dense([x, e]) is the bound layer: W_x x + W_e e + b."""
  z = jax.random.normal(jax.random.key(1), (5, 16))
  e = tasks.embed(mt_params, 4)
  layer = mt_params['actor']['mlp']['dense_0']
  w_e = mt_params['task']['proj']['actor']['mlp']['dense_0']
  concat = jnp.concatenate([z, jnp.broadcast_to(e, (5, e.shape[0]))], -1) @ jnp.concatenate(
      [layer['kernel'], w_e]) + layer['bias']
  bound = tasks.bind(mt_params, 4)['actor']['mlp']['dense_0']
  np.testing.assert_allclose(z @ bound['kernel'] + bound['bias'], concat, rtol=1e-5, atol=1e-5)


def test_task_conditioning_changes_every_network(mt_config, mt_params):
  nets = models.build_networks(ModelSettings.from_config(mt_config))
  p0, p1 = tasks.bind(mt_params, 0), tasks.bind(mt_params, 1)
  obs = jax.random.normal(jax.random.key(2), (3, 39))
  h, a_dim = mt_config.horizon, mt_config.action_dim
  z = models.encode(p0, obs)
  a = jnp.zeros((3, h, a_dim))
  t = jnp.full((3,), 0.5)
  outputs = {
      'encoder': lambda p: models.encode(p, obs),
      'actor': lambda p: nets.actor.apply({'params': p['actor']}, z),
      'proposal': lambda p: nets.proposal.apply({'params': p['proposal']}, a, t, z),
      'dynamics': lambda p: nets.dynamics.apply({'params': p['dynamics']}, z, t, z, a[:, 0]),
      'objective': lambda p: nets.objective.apply({'params': p['objective']},
                                                  jnp.stack([z] * (h + 1), 1), a)[0],
      'critics': lambda p: nets.critics.apply({'params': p['critics']}, z, method=Critics.value),
  }
  for name, fn in outputs.items():
    gap = float(jnp.max(jnp.abs(fn(p0) - fn(p1))))
    assert gap > 1e-3, name
    np.testing.assert_allclose(fn(p0), fn(tasks.bind(mt_params, 0)), err_msg=name)
  plan = make_plan(mt_config)
  key = jax.random.key(3)
  scores = [plan(p, models.encode(p, obs[0]), key).scores for p in (p0, p1)]
  assert float(jnp.max(jnp.abs(scores[0] - scores[1]))) > 1e-4


def test_multitask_loss_trains_each_task_on_its_share(mt_config, mt_params):
  nets = models.build_networks(ModelSettings.from_config(mt_config))
  loss = tasks.multitask_loss(make_loss_fn(ModelSettings.from_config(mt_config),
      LossSettings.from_config(mt_config), nets), 10)
  h, b = mt_config.horizon, 2
  rng = np.random.default_rng(0)
  batch = dict(obs=rng.normal(size=(10 * b, h + 2, 39)).astype(np.float32),
               action=rng.uniform(-1, 1, (10 * b, h + 1, 4)).astype(np.float32),
               reward=rng.uniform(0, 1, (10 * b, h + 1)).astype(np.float32),
               task=np.repeat(np.arange(10, dtype=np.int32), b))
  key = jax.random.key(4)
  value_and_grad = jax.jit(jax.value_and_grad(lambda p, batch: loss(p, mt_params, batch, key),
                                              has_aux=True))
  (total, metrics), grads = value_and_grad(mt_params, batch)
  assert np.isfinite(total) and total > 0
  np.testing.assert_allclose(metrics['loss'], total, rtol=1e-6)
  emb = np.abs(np.asarray(grads['task']['embedding'])).sum(1)
  assert np.all(emb > 0)  # Every task's embedding is trained by its share.
  # The same arrays labelled as task 3 only: only task 3's embedding gets a gradient.
  (_, _), grads = value_and_grad(mt_params, dict(batch, task=np.full(10 * b, 3, np.int32)))
  emb = np.abs(np.asarray(grads['task']['embedding'])).sum(1)
  assert emb[3] > 0 and np.all(np.delete(emb, 3) == 0), emb
  with pytest.raises(ValueError, match='does not split over 10 tasks'):
    loss(mt_params, mt_params, {k: v[:15] for k, v in batch.items()}, key)
