r"""A multi-task run on Meta-World's own MT10 benchmark, evaluated as Meta-World evaluates it.

  python -m experiments.evaluate mt10 --workdir=runs/mt10_cpu --modes=plan,actor,proposal

Builds `gym.make_vec('Meta-World/MT10', vector_strategy='sync', seed=--seed)` (ten environments,
env k is task k of MT10, each resetting to one of its 50 goals drawn at random) and runs
`metaworld.evaluation.evaluation(agent, envs, --episodes)` for each policy: success terminates an
episode, at most 500 environment steps, the first --episodes episodes of every task count.
Meta-World steps once per action; the agent repeats each decision `config.eval.action_repeat`
times, as in training. Also reports how many counted episodes started on a goal of the training
data (MT10's goals are not held out). Writes <workdir>/metaworld_mt10_seed<S>.json and .md (S:
--seed), or --out and the .md beside it, after every policy; an existing file is kept unless
--overwrite. Where this protocol differs from `experiments.train`'s: docs/mt10.md.
"""

import json
import os

from absl import app, flags, logging

from ld_mpc_jax.cli import errors as cli
from ld_mpc_jax.plan.modes import ActSettings

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training workdir of a multi-task run.')
_MODES = flags.DEFINE_list('modes', ['plan', 'actor', 'proposal'], 'Policies to evaluate.')
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Episodes per task (metaworld default 50).')
_SEED = flags.DEFINE_integer('seed', 0, "MT10's seed: its goals and resets.")
_OUT = flags.DEFINE_string('out', None, 'JSON output, .md beside '
                           '(default: <workdir>/metaworld_mt10_seed<S>.json).')
_OVERWRITE = flags.DEFINE_bool('overwrite', False, 'Replace an existing --out file.')
flags.mark_flags_as_required(['workdir'])


class MT10Agent:
  """metaworld.evaluation's Agent: one jitted act per environment, with its task's parameters.

  Environment i acts for task index `task_ids[i]` with `tasks.bind(params, task_ids[i])` and the
  policy of `act` (a task's ActSettings: EvalSpec.tasks); a decision is held for `repeat`
  environment steps (config.eval.action_repeat); warm starts and decision keys restart with
  each episode (fold_in(fold_in(key(seed), episode), t)). An environment whose task has its
  `episodes` counted episodes does not plan any more (zero actions) while the others finish.
  Records whether each episode started on one of the training data's goals
  (`on_train_goal[i]`, in episode order).
  """

  def __init__(self, act: ActSettings, repeat: int, params, mode, task_ids, train_goals, seed,
               episodes, bar):
    import jax
    from ld_mpc_jax.plan import agent
    from ld_mpc_jax.model import tasks
    self.act = agent.make_act(act, mode)
    self.params = [tasks.bind(params, k) for k in task_ids]
    self.task_ids, self.train_goals, self.repeat = task_ids, train_goals, repeat
    self.key, self.episodes, self.bar = jax.random.key(seed), episodes, bar
    n = len(task_ids)
    self.episode, self.step = [-1] * n, [0] * n
    self.prev, self.action, self.fresh = [None] * n, [None] * n, [True] * n
    self.on_train_goal = [[] for _ in range(n)]

  def reset(self, env_mask):
    for i in map(int, env_mask.nonzero()[0]):
      if 0 <= self.episode[i] < self.episodes:
        self.bar.update(1)  # Only the episodes that count (the first `episodes` of each task).
      self.episode[i] += 1
      self.step[i], self.prev[i], self.fresh[i] = 0, None, True

  def eval_action(self, observations):
    import jax
    import numpy as np
    from ld_mpc_jax.envs import goals, metaworld_env
    out = np.zeros((len(self.params), 4), np.float32)
    for i, obs in enumerate(observations):
      if self.episode[i] >= self.episodes:
        continue  # This task has all its counted episodes: its actions no longer matter.
      if self.fresh[i]:
        vector = metaworld_env.goal_vector(obs)
        self.on_train_goal[i].append(bool(goals.matches(vector, self.train_goals[i])[0]))
        self.fresh[i] = False
      if self.step[i] % self.repeat == 0:
        key = jax.random.fold_in(self.key, self.episode[i])
        action, self.prev[i], _ = self.act(self.params[i], np.asarray(obs, np.float32), key,
                                           self.step[i] // self.repeat, self.prev[i])
        self.action[i] = np.asarray(action)
      out[i] = self.action[i]
      self.step[i] += 1
    return out


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)  # Keep orbax's INFO lines out of the output.
  import gymnasium as gym
  import metaworld  # pylint: disable=unused-import (registers Meta-World/MT10)
  from metaworld import evaluation as mw_evaluation
  import numpy as np
  import tqdm
  from ld_mpc_jax.plan import agent
  from ld_mpc_jax.learn import checkpointing
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.eval import evaluation_suite
  from ld_mpc_jax.eval.spec import EvalSpec
  from ld_mpc_jax.ops import stats
  from ld_mpc_jax.model import tasks
  try:  # Bad input: one line and exit code 2.
    config = checkpointing.load_config(_WORKDIR.value)
    cli.check_new_output(_out_path(), _OVERWRITE.value)
    bad = set(_MODES.value) - set(agent.MODES)
    if bad or not _MODES.value or _EPISODES.value < 1:
      raise ValueError(f'--modes must be among {agent.MODES} and --episodes >= 1, got '
                       f'{_MODES.value}, {_EPISODES.value}')
    if not tasks.Tasks.from_config(config).multitask:
      raise ValueError(f'{_WORKDIR.value} is a single-task run ({config.task}); MT10 needs a '
                       'multi-task one (config.tasks)')
    _, params, step = run_checks.load_for_evaluation(_WORKDIR.value)
    spec = EvalSpec.from_config(config)  # Each task's spec: spec.tasks.
  except (ValueError, FileNotFoundError) as err:
    cli.fail(str(err))
  envs = gym.make_vec('Meta-World/MT10', vector_strategy='sync', seed=_SEED.value)
  names = mw_evaluation._get_task_names(envs)  # pylint: disable=protected-access
  missing = [n for n in names if n not in spec.task_names]
  if missing:
    cli.fail(f'the run was not trained on MT10 tasks {missing}')
  task_ids = [spec.task_names.index(n) for n in names]
  train_goals = [evaluation_suite.dataset_goals(spec.tasks[k][1].goals)[0] for k in task_ids]
  results = {}
  for mode in _MODES.value:
    with tqdm.tqdm(total=len(names) * _EPISODES.value, desc=f'MT10 {mode}') as bar:
      policy = MT10Agent(spec.tasks[0][1].act, spec.eval.action_repeat, params, mode, task_ids,
                         train_goals, _SEED.value, _EPISODES.value, bar)
      mean, mean_return, per_task, _ = mw_evaluation.evaluation(policy, envs, _EPISODES.value)
    on_train = {n: float(np.mean(policy.on_train_goal[i][:_EPISODES.value]))
                for i, n in enumerate(names)}
    results[mode] = dict(success_rate=mean, mean_return=mean_return, per_task=per_task,
                         per_task_ci95={n: stats.wilson_interval(round(r * _EPISODES.value),
                                                                 _EPISODES.value)
                                        for n, r in per_task.items()},
                         share_on_train_goals=on_train)
    print(f'{mode}: Meta-World MT10 success {mean:.3f}', flush=True)
    md = _write(names, step, results)  # After every policy: nothing lost on a crash.
  envs.close()
  print(md)


def _out_path():
  """The JSON file written: --out (its extension made .json) or the workdir's default."""
  if _OUT.value:
    return os.path.splitext(_OUT.value)[0] + '.json'
  return os.path.join(_WORKDIR.value, f'metaworld_mt10_seed{_SEED.value}.json')


def _write(names, step, results):
  """Writes the JSON output and the .md beside it (policies so far); returns the md."""
  from ld_mpc_jax.eval import evaluation_suite
  stem = os.path.splitext(_out_path())[0]
  os.makedirs(os.path.dirname(os.path.abspath(stem)), exist_ok=True)
  out = dict(workdir=_WORKDIR.value, step=step, seed=_SEED.value, episodes=_EPISODES.value,
             protocol='metaworld.evaluation.evaluation on gym.make_vec("Meta-World/MT10")',
             results=results)
  with open(stem + '.json', 'w') as f:
    json.dump(out, f, indent=1)
  lines = [f'# Meta-World MT10 protocol, step {step}, MT10 seed {_SEED.value}, '
           f'{_EPISODES.value} episodes per task', '',
           '| task | ' + ' | '.join(evaluation_suite.POLICY_NAMES[m] for m in results)
           + ' | counted episodes on training goals |', '| --- |' + ' --- |' * (len(results) + 1)]
  for n in names:
    cells = [f"{r['per_task'][n]:.2f} [{r['per_task_ci95'][n][0]:.2f}, "
             f"{r['per_task_ci95'][n][1]:.2f}]" for r in results.values()]
    share = next(iter(results.values()))['share_on_train_goals'][n]
    lines.append(f'| {n} | ' + ' | '.join(cells) + f' | {share:.2f} |')
  lines.append('| **average** | ' + ' | '.join(f"**{r['success_rate']:.3f}**"
                                              for r in results.values()) + ' | |')
  md = '\n'.join(lines) + '\n'
  with open(stem + '.md', 'w') as f:
    f.write(md)
  return md
