r"""Behaviour-cloning baseline: MLP policy trained on a dataset preset.

  python -m experiments.evaluate bc --task=door-open-v3 --preset=mixed \
      --episodes=200 --data_dir=runs/data --out=runs/bc_mixed.json

Gets the dataset with `get_or_collect` (cached .npz), regresses actions on
normalised observations with an MSE loss (tanh-squashed MLP), then evaluates
the policy with the Meta-World protocol (`ld_mpc_jax.eval.evaluation.evaluate`) on
held-out goals (`--split=held_out`, the default: the episodes the planner's
evaluation uses at the same evaluation seed) or on the data's own (`--split=train`).
The JSON keeps every episode's outcome.

  python -m experiments.evaluate bc --run=runs/sparse/seed0 --out=runs/sparse/seed0/bc.json

With --run (an online run with `online.demos`), BC learns from that run's own demonstrations
(the same scripted episodes, `OnlineSettings.demonstrations`) and is evaluated on the episodes
of that run's final evaluation (held-out goals, its evaluation seeds), so that it pairs with the
run's episodes.csv episode by episode.
"""

import json
import os
import time

from absl import app
from absl import flags
import jax
import jax.numpy as jnp
import numpy as np
import optax

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax import envs
from ld_mpc_jax.eval import evaluation
from ld_mpc_jax.data import collection
from ld_mpc_jax.data import replay
from ld_mpc_jax.nets.mlp import MLP

_TASK = flags.DEFINE_string('task', 'door-open-v3', 'Meta-World v3 task.')
_PRESET = flags.DEFINE_enum('preset', 'mixed', list(collection.PRESETS),
                            'Dataset preset.')
_EPISODES = flags.DEFINE_integer('episodes', 200, 'Dataset episodes.')
_SEED = flags.DEFINE_integer('seed', 0, 'Data, training and evaluation seed.')
_DATA_DIR = flags.DEFINE_string('data_dir', 'data_cache', 'Dataset cache.')
_STEPS = flags.DEFINE_integer('steps', 20000, 'Gradient steps.')
_BATCH = flags.DEFINE_integer('batch_size', 256, 'Batch size.')
_LR = flags.DEFINE_float('lr', 3e-4, 'Adam learning rate.')
_HIDDEN = flags.DEFINE_integer('hidden', 256, 'Hidden width (2 layers).')
_EVAL_EPISODES = flags.DEFINE_integer('eval_episodes', 50, 'Protocol episodes.')
_OUT = flags.DEFINE_string('out', None, 'Where to write the JSON result.')
_RUN = flags.DEFINE_string('run', None, 'An online training workdir with demonstrations: BC on '
                           'its demonstrations, evaluated on its final evaluation episodes.')
_NOISE = flags.DEFINE_list('noise_stds', [], 'Also evaluate under these observation-noise stds '
                           '(the same episodes; records in the JSON\'s noise_sweep, as '
                           'experiments.evaluate --noise_sweep writes them).')
_SPLIT = flags.DEFINE_enum('split', 'held_out', list(envs.SUITE.goal_splits),
                           "Evaluation goals: 'held_out' (absent from the data) or 'train'.")


def train_bc(ds, steps, batch_size, lr, hidden, seed):
  """Fits tanh(MLP(normalised obs)) to actions; returns policy, final loss."""
  mask = ds.transition_mask()
  mean = ds.observations[mask].mean(0)
  std = ds.observations[mask].std(0)
  # Features constant in the data are left out (as the encoder's model.obs_mask_constant):
  # their (x - mean) / 1e6 is ~0 for any reading, noise included; the others as before.
  std = np.where(std <= 1e-6, 1e6, std + 1e-3)
  net = MLP((hidden, hidden, ds.act_dim))
  params = net.init(jax.random.PRNGKey(seed), jnp.zeros((1, ds.obs_dim)))
  tx = optax.adam(lr)
  opt_state = tx.init(params)

  def apply(p, obs):
    return jnp.tanh(net.apply(p, (obs - mean) / std))

  @jax.jit
  def update(p, o_state, obs, act):
    loss, grads = jax.value_and_grad(
        lambda q: jnp.mean((apply(q, obs) - act) ** 2))(p)
    updates, o_state = tx.update(grads, o_state, p)
    return optax.apply_updates(p, updates), o_state, loss

  buffer = replay.ReplayBuffer(ds, seq_len=2, seed=seed)
  loss = None
  for _ in range(steps):
    batch = buffer.sample(batch_size)
    params, opt_state, loss = update(params, opt_state, batch['obs'][:, 0],
                                     batch['action'][:, 0])
  act_fn = jax.jit(lambda p, o: apply(p, o[None])[0])
  policy = lambda obs: np.asarray(act_fn(params, jnp.asarray(obs, jnp.float32)))
  return policy, float(loss)


def _run_demos(workdir):
  """(demonstrations as a Dataset, the run's final-evaluation episodes, task, seed) of an online
  run with `online.demos`."""
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.eval import evaluation_suite  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.eval.spec import GoalSource  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.data import dataset  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.online.settings import OnlineSettings  # pylint: disable=g-import-not-at-top
  with cli.one_line_errors():
    config = checkpointing.load_config(workdir)
    if 'online' not in config or not config.online.demos:
      raise ValueError(f'--run={workdir!r} is not an online run with demonstrations')
  ds = dataset.Dataset.from_episodes(OnlineSettings.from_config(config).demonstrations(),
                                     metadata=dict(action_repeat=config.eval.action_repeat))
  source = GoalSource.from_config(config)
  episodes = [ep for split in config.eval.splits for s in config.eval.seeds
              for ep in evaluation_suite.episodes(source, split, s, config.eval.episodes)][
                  :config.eval.episodes]
  return ds, episodes, config.task, config.seed


def main(argv):
  del argv
  with cli.one_line_errors():
    envs.check_task(_TASK.value)
    for name in ('episodes', 'steps', 'batch_size', 'hidden', 'eval_episodes'):
      if flags.FLAGS[name].value < 1:
        raise ValueError(f'--{name} must be >= 1, got {flags.FLAGS[name].value}')
  if _RUN.value:
    ds, episodes, task, seed = _run_demos(_RUN.value)
  else:
    ds = collection.get_or_collect(_TASK.value, _PRESET.value, _EPISODES.value,
                                   _SEED.value, _DATA_DIR.value)
    # The data were collected on the goals of MT1 seed --seed (collection.get_or_collect).
    episodes = envs.SUITE.make_episodes(_TASK.value, _SPLIT.value, _SEED.value,
                                        _EVAL_EPISODES.value,
                                        envs.SUITE.dataset_goal_vectors(ds), _SEED.value)
    task, seed = _TASK.value, _SEED.value
  start = time.time()
  policy, loss = train_bc(ds, _STEPS.value, _BATCH.value, _LR.value, _HIDDEN.value, seed)
  train_s = time.time() - start
  start = time.time()
  res = evaluation.evaluate(policy, task, episodes=episodes,
                            action_repeat=ds.metadata['action_repeat'])
  report = dict(task=task, preset=_PRESET.value if not _RUN.value else 'demos',
                run=_RUN.value, split=episodes[0].split,
                outcomes=[dict(ep.record(), success=int(o))
                          for ep, o in zip(episodes, res['outcomes'])],
                # Records as a run's episodes.csv names them (policy 'bc'; with --run, its seed as
                # `run`; without, none, so that a join takes the run it is joined with), so that
                # experiments.report pairs them with the run's own.
                records=[dict(ep.record(), policy='bc', success=int(o),
                              **(dict(run=seed) if _RUN.value else {}))
                         for ep, o in zip(episodes, res['outcomes'])],
                dataset=collection.summary(ds), final_loss=loss,
                train_seconds=round(train_s, 1),
                eval_seconds=round(time.time() - start, 1),
                **{k: res[k] for k in ('success_rate', 'success_ci95',
                                       'mean_return', 'mean_length',
                                       'decisions_per_s', 'num_episodes')})
  if _NOISE.value:  # Records as evaluate's noise sweep names them, so that they pair with it.
    sweep = []
    for std in [float(x) for x in _NOISE.value]:
      out = evaluation.evaluate(policy, task, episodes=episodes, obs_noise_std=std,
                                action_repeat=ds.metadata['action_repeat'])
      sweep += [dict(ep.record(), run=seed, policy='bc', success=int(o), obs_noise=std)
                for ep, o in zip(episodes, out['outcomes'])]
      print(f"bc, obs noise {std}: {out['success_rate']:.2f}")
    report['noise_sweep'] = dict(records=sweep)
  text = json.dumps(report, indent=1)
  print(text)
  if _OUT.value:
    os.makedirs(os.path.dirname(os.path.abspath(_OUT.value)), exist_ok=True)
    with open(_OUT.value, 'w') as f:
      f.write(text)
