"""Planner with a fallback: once J of the actor prior's own sequence (the state's value as the
objective sees it) drops more than DROP (a fraction) below its running maximum in the episode,
the planner executes the actor prior's sequence for the rest of the episode.
  python fallback_plan.py WORKDIR TASK EPISODES(comma|all) VARIANT DROP OUT
"""
import json, sys
import jax, jax.numpy as jnp, numpy as np
from ld_mpc_jax import agent, checkpointing, diagnostics, evaluation, evaluation_suite, models, tasks, planner
from ld_mpc_jax.search import first_round_counts
from experiments import overrides

workdir, task, eps_arg, variant, drop, out = sys.argv[1:7]
drop = float(drop)
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
def body(params, obs, key, t, prev):
  z = models.encode(params, obs)
  o = plan(params, z, jax.random.fold_in(key, t), prev)
  return o.action, o.sequence, o.departed, o.scores[anchor], o.candidates[anchor]
step = jax.jit(body)
step0 = jax.jit(lambda params, obs, key, t: body(params, obs, key, t, None))
e = config.eval
seed = 0
key_seed = seed if e.key_seed < 0 else e.key_seed
class P:
  def start(self, episodes):
    self.key = agent.episode_keys(key_seed, [episodes[0].reset_seed])[0]; self.prev = None; self.rows = []
    self.jmax = -np.inf; self.off = False
  def __call__(self, obs, t, active):
    o = jnp.asarray(obs[0], jnp.float32)
    a, seq, dep, ja, aseq = step0(params, o, self.key, t) if self.prev is None else step(params, o, self.key, t, self.prev)
    ja = float(ja)
    self.jmax = max(self.jmax, ja)
    if drop > 0 and self.jmax > 0 and ja < (1 - drop) * self.jmax:
      self.off = True
    if self.off:
      a, seq, dep = aseq[0], aseq, False
    if config.plan.warm_start_steps > 0: self.prev = seq
    self.rows.append(dict(t=int(t), departed=bool(dep), j_actor=ja, off=self.off))
    return np.asarray(a)[None]
pol = P()
eps = evaluation_suite.episodes(config, 'held_out', seed, 50)
idx = range(50) if eps_arg == 'all' else [int(x) for x in eps_arg.split(',')]
res = []
for i in idx:
  recs, _ = evaluation.run_episodes(pol, [eps[i]], config.task, batch_size=1, action_repeat=e.action_repeat,
      max_episode_steps=e.max_episode_steps, progress=False)
  off_at = next((r['t'] for r in pol.rows if r['off']), None)
  res.append(dict(episode=i, success=int(recs[0]['success']), first_success=recs[0]['first_success'],
                  length=len(pol.rows), departures=sum(r['departed'] for r in pol.rows), off_at=off_at))
  print(i, recs[0]['success'], recs[0]['first_success'], len(pol.rows), 'off_at', off_at, flush=True)
json.dump(dict(workdir=workdir, task=task, variant=variant, drop=drop, episodes=res), open(out, 'w'))
print('solved', sum(r['success'] for r in res), 'of', len(res))
