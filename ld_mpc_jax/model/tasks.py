"""Multi-task agents: a learned task embedding, as TD-MPC2 conditions on the task.

A config with `config.tasks` (two or more Meta-World task names) trains one agent for all of
them. TD-MPC2 looks up a learned embedding e_k of task k, clips it to at most unit norm
(`nn.Embedding(max_norm=1)`), and concatenates it to the input of the encoder and of every
network that reads a latent. A Dense layer of [x, e] is W_x x + W_e e + b: the same layer with the
task-dependent bias b + W_e e. So here the networks stay exactly as a single-task agent's, and
the task enters through that bias of each network's input layer (`input_layers`: those of
`INPUT_LAYERS`, and for the proposal and the dynamics those their kind's entry declares as its
`conditioning`; a declared layer the parameters lack is an error, so no network goes silently
unconditioned):

  params['task'] = {'embedding': [num_tasks, task_dim], 'proj': {net: {layer: W_e}}},

with W_e of shape [task_dim] + bias shape. `bind(params, k)` adds W_e e_k to those biases and
drops params['task']: the result is a single-task agent's parameter tree for task k, which every
single-task function (encode, plan, the policies, the evaluation) takes unchanged. Training
applies the single-task loss to each task's share of a task-balanced batch under vmap
(`multitask_loss`).

Single-task configs (no `config.tasks`, or one task) have no 'task' entry: the same parameter
tree as before, so older checkpoints load.
"""

from typing import Callable, Dict, Tuple

import flax
import jax
import jax.numpy as jnp

# A config's task names (`Tasks.from_config`) live with the environments (data and evaluation
# use them too); re-exported here for the model's callers.
from ld_mpc_jax.envs.tasks import Tasks
from ld_mpc_jax.model.settings import ModelSettings

# The layers that read a network's input (the observation for the encoder, a latent for the
# others), by parameter path within the network, for the networks that have one kind; the
# proposal's and the dynamics' come from their kind's entry (`conditioning`).
INPUT_LAYERS = {
    'encoder': (('mlp', 'dense_0'),),
    'objective': (('z_proj',),),
    'actor': (('mlp', 'dense_0'),),
    'critics': (('v', 'heads', 'dense_0'), ('q', 'heads', 'dense_0')),
}
NETWORKS = ('encoder', 'proposal', 'dynamics', 'objective', 'actor', 'critics')


def input_layers(m: ModelSettings) -> Dict[str, Tuple[Tuple[str, ...], ...]]:
  """{network: parameter paths of its task-conditioned input layers}, in NETWORKS order."""
  from ld_mpc_jax.model import dynamics, proposals  # pylint: disable=g-import-not-at-top
  kinds = {'proposal': proposals.get(m).conditioning, 'dynamics': dynamics.get(m).conditioning}
  return {net: tuple(kinds[net] if net in kinds else INPUT_LAYERS[net]) for net in NETWORKS}


def init_task_params(m: ModelSettings, key: jax.Array, params: dict) -> dict:
  """`params` plus params['task'] for a multi-task config; unchanged for a single task.

  The embedding starts N(0, 1) like torch's nn.Embedding (clipped to unit norm when used); each
  W_e is LeCun-normal over the task_dim inputs it adds to its layer.
  """
  if not m.multitask:
    return params
  dim = m.task_dim
  k_emb, k_proj = jax.random.split(key)
  proj, i = {}, 0
  for net, paths in input_layers(m).items():
    if net not in params:  # The critics, for a model without them.
      continue
    for path in paths:
      layer = _lookup(params[net], path)
      if layer is None:
        raise ValueError(f'task conditioning: params[{net!r}] has no input layer '
                         f'{"/".join(path)!r} (its kind\'s `conditioning`)')
      shape = (dim,) + layer['bias'].shape
      w = jax.random.normal(jax.random.fold_in(k_proj, i), shape) * dim ** -0.5
      proj[(net,) + path] = w
      i += 1
  embedding = jax.random.normal(k_emb, (m.num_tasks, dim))
  return dict(params, task={'embedding': embedding,
                            'proj': flax.traverse_util.unflatten_dict(proj)})


def _lookup(tree: dict, path: Tuple[str, ...]):
  for part in path:
    if not isinstance(tree, dict) or part not in tree:
      return None
    tree = tree[part]
  return tree


def embed(params: dict, task: jnp.ndarray) -> jnp.ndarray:
  """Task index [] -> embedding [task_dim], scaled to norm at most 1 (TD-MPC2's max_norm=1)."""
  e = params['task']['embedding'][task]
  return e / jnp.maximum(1.0, jnp.linalg.norm(e))


def bind(params: dict, task) -> dict:
  """A multi-task parameter tree restricted to task index `task` (a Python or traced scalar).

  Returns the single-task tree (no 'task' entry) whose input-layer biases are b + W_e e_task;
  a tree without 'task' is returned as it is.
  """
  if 'task' not in params:
    return params
  e = embed(params, jnp.asarray(task))
  flat = flax.traverse_util.flatten_dict({k: v for k, v in params.items() if k != 'task'})
  for path, w in flax.traverse_util.flatten_dict(params['task']['proj']).items():
    bias = path + ('bias',)
    flat[bias] = flat[bias] + jnp.tensordot(e, w, axes=1)
  return flax.traverse_util.unflatten_dict(flat)


def multitask_loss(loss_fn: Callable, num: int) -> Callable:
  """The single-task loss on each task's share of a task-balanced batch, averaged.

  batch: the single-task arrays [B, ...] plus 'task' int32 [B], task-major: B = num * b rows,
  rows g*b .. g*b + b - 1 all of one task (`data.multitask.TaskBalancedBuffer`). The loss of
  each share uses `bind(params, task)` (and the same for the EMA target parameters); the total
  and the metrics are the means over the shares, i.e. over the batch, as the shares are equal.
  """

  def loss(params, target_params, batch, key):
    size = batch['task'].shape[0]
    if size % num:
      raise ValueError(f'a multi-task batch of {size} rows does not split over {num} tasks')
    groups = {k: v.reshape((num, size // num) + v.shape[1:]) for k, v in batch.items()}
    task_ids = groups.pop('task')[:, 0]

    def one(task, share, k):
      return loss_fn(bind(params, task), bind(target_params, task), share, k)

    losses, metrics = jax.vmap(one)(task_ids, groups, jax.random.split(key, num))
    return losses.mean(), jax.tree_util.tree_map(jnp.mean, metrics)

  return loss
