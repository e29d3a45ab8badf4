"""Per-decision trace of the planner on chosen held-out episodes of one task of a checkpoint:
departed, J of the actor prior's own sequence (as scored by the first round), the winner's J,
the environment's reward and info terms. Key schedule as agent.BatchAgentPolicy.
  python trace_plan.py WORKDIR TASK EPISODES(comma) VARIANT OUT
"""
import json, sys
import jax, jax.numpy as jnp, numpy as np
from ld_mpc_jax import agent, checkpointing, diagnostics, evaluation, evaluation_suite, models, tasks, planner
from ld_mpc_jax.search import first_round_counts
from experiments import overrides

workdir, task, eps_arg, variant, out = sys.argv[1:6]
config, params, _ = checkpointing.load_for_evaluation(workdir)
names = tasks.task_names(config)
if len(names) > 1:
  k = names.index(task)
  config, params = tasks.task_config(config, k), tasks.bind(params, k)
if variant:
  _, items = overrides.parse_variant(variant)
  config = overrides.with_overrides(config, items)
plan = planner.make_plan(config)
anchor = sum(n for _, n in first_round_counts(config))
@jax.jit
def step(params, obs, key, t, prev):
  z = models.encode(params, obs)
  o = plan(params, z, jax.random.fold_in(key, t), prev)
  return o.action, o.sequence, o.departed, o.scores[anchor], o.scores[o.index], jnp.max(o.scores)
@jax.jit
def step0(params, obs, key, t):
  z = models.encode(params, obs)
  o = plan(params, z, jax.random.fold_in(key, t), None)
  return o.action, o.sequence, o.departed, o.scores[anchor], o.scores[o.index], jnp.max(o.scores)
e = config.eval
seed = 0
key_seed = seed if e.key_seed < 0 else e.key_seed
class P:
  def start(self, episodes):
    self.key = agent.episode_keys(key_seed, [episodes[0].reset_seed])[0]; self.prev = None; self.rows = []
  def __call__(self, obs, t, active):
    o = jnp.asarray(obs[0], jnp.float32)
    r = step0(params, o, self.key, t) if self.prev is None else step(params, o, self.key, t, self.prev)
    a, seq, dep, ja, jw, jmax = r
    if config.plan.warm_start_steps > 0: self.prev = seq
    self.rows.append(dict(t=int(t), departed=bool(dep), j_actor=float(ja), j_exec=float(jw), j_max=float(jmax)))
    return np.asarray(a)[None]
pol = P()
eps = evaluation_suite.episodes(config, 'held_out', seed, 50)
res = []
for i in [int(x) for x in eps_arg.split(',')]:
  log = []
  recs, _ = evaluation.run_episodes(pol, [eps[i]], config.task, batch_size=1, action_repeat=e.action_repeat,
      max_episode_steps=e.max_episode_steps, env_factory=lambda **kw: diagnostics._Recorder(log, **kw), progress=False)
  steps = log[-1]
  res.append(dict(episode=i, success=int(recs[0]['success']), first_success=recs[0]['first_success'],
                  decisions=[dict(r, **steps[r['t']]) for r in pol.rows]))
  print(i, recs[0]['success'], recs[0]['first_success'], len(pol.rows), flush=True)
json.dump(dict(workdir=workdir, task=task, variant=variant, episodes=res), open(out, 'w'))
