"""Diagnostics of the planner's objective (experiments.diagnose, docs/objective.md).

  held_out_windows      windows (o_t, a_{t:t+H}) and Monte Carlo returns of held-out dataset
                        episodes: the config's task and preset, data seed + 1000;
  objective_correlation Spearman of J (dynamics rollout; encoder latents) against those returns;
  candidate_wins        share of plans won by each candidate kind;
  success_by_k          planner success on held-out goals for each K, paired with the largest K.
  trace_episodes        the environment's reward terms per decision in chosen held-out episodes;
  departure_gains       what each departure from the actor prior gains in J, split into the
                        horizon's rewards and the terminal value, in chosen held-out episodes.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from scipy import stats as sps

from ld_mpc_jax import data
from ld_mpc_jax.eval import evaluation, evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.model import models, objective
from ld_mpc_jax.ops import stats
from ld_mpc_jax.plan import agent, planner
from ld_mpc_jax.plan.modes import ActSettings
from ld_mpc_jax.ops.numerics import discounted_return, two_hot_decode


_HORIZON_MARGIN = 100  # Decisions of return a window needs after its start (1 / (1 - gamma)).


def held_out_windows(spec: EvalSpec, data_episodes: int, stride: int):
  """(obs [N, H+1, obs_dim], actions [N, H, A], returns [N]) from held-out dataset episodes."""
  d, m = spec.goals.data, spec.act.model
  h = m.horizon
  ds = data.get_or_collect(d.task, d.preset, data_episodes, d.seed + 1000, d.dir,
                           action_repeat=d.action_repeat)
  obs, acts, rets = [], [], []
  for e in range(ds.num_episodes):
    ep = ds.episode(e)
    rewards = ep['reward']
    returns = np.zeros(len(rewards) + 1)
    for t in range(len(rewards) - 1, -1, -1):
      returns[t] = rewards[t] + m.gamma * returns[t + 1]
    for t in range(0, max(len(rewards) - _HORIZON_MARGIN, 1), stride):
      if t + h <= len(rewards):
        obs.append(ep['obs'][t:t + h + 1])
        acts.append(ep['action'][t:t + h])
        rets.append(returns[t])
  return np.stack(obs), np.stack(acts), np.asarray(rets)


def objective_correlation(act: ActSettings, params, obs, actions, returns) -> dict:
  """Spearman of J (dynamics rollout and encoder latents) against Monte Carlo returns."""
  m, p = act.model, act.plan
  nets = models.build_networks(m)
  score = objective.make_score(m, nets, p.pessimism, p.progress_weight)
  rollout = planner.make_rollout(m, dataclasses.replace(p, num_prior_candidates=0), nets)

  @jax.jit
  def both(obs, actions, key):
    z = models.encode(params, obs)  # [N, H+1, D]
    j_encoder = score(params, z, actions)
    def model_j(z0, seq, k):
      acts, latents = rollout(params, z0, seq[None], k)
      return score(params, latents, acts)[0]
    keys = jax.random.split(key, obs.shape[0])
    return jax.vmap(model_j)(z[:, 0], actions, keys), j_encoder

  j_model, j_encoder = map(jnp.asarray, both(jnp.asarray(obs, jnp.float32),
                                             jnp.asarray(actions, jnp.float32),
                                             jax.random.key(0)))
  rho = lambda j: float(sps.spearmanr(j, returns).statistic)
  return dict(windows=int(len(returns)), spearman_model=rho(j_model),
              spearman_encoder=rho(j_encoder))


def candidate_wins(act: ActSettings, params, obs) -> dict:
  """Fraction of plans won by each candidate kind, planning from each state obs [N, obs_dim]."""
  plan = planner.build_plan(act.model, act.plan)
  z = models.encode(params, obs)
  kinds = [int(plan(params, z[i], jax.random.key(i)).kind) for i in range(len(obs))]
  names = planner.CANDIDATES.names()
  counts = np.bincount(kinds, minlength=len(names))
  return {kind: float(c / len(kinds)) for kind, c in zip(names, counts)}


def departures(records) -> dict:
  """The share of the planner's decisions that left the actor prior's own sequence, and the
  success of episodes with at least one such decision and of those with none."""
  decisions = sum(r['length'] for r in records)
  went = [r for r in records if r.get('departures', 0) > 0]
  stayed = [r for r in records if r.get('departures', 0) == 0]
  solved = lambda rs: [sum(r['success'] for r in rs), len(rs)]
  return dict(departure_share=sum(r.get('departures', 0) for r in records) / max(decisions, 1),
              success_with_departures=solved(went), success_without_departures=solved(stayed))


def success_by_k(spec: EvalSpec, params, ks, episodes: int, seed: int) -> list:
  """Planner success on held-out goals per K, paired with the largest K."""
  p = spec.act.plan
  rows, outcomes = [], {}
  for k in ks:
    prior = round(p.num_prior_candidates * k / p.num_candidates) if k > 1 else 0
    with_k = spec.with_plan(num_candidates=k, num_prior_candidates=prior)
    r = evaluation_suite.evaluate_policy(with_k, params, 'plan', episodes, seed, 'held_out')
    outcomes[k] = [rec['success'] for rec in sorted(r['records'], key=lambda x: x['episode'])]
    rows.append(dict(k=k, prior=prior, successes=r['successes'], episodes=episodes,
                     success_rate=r['success_rate'], success_ci95=r['success_ci95'],
                     **departures(r['records'])))
  top = max(ks)
  for row in rows:
    row['vs_largest_k'] = stats.mcnemar_exact(outcomes[row['k']], outcomes[top])
  return rows


def _ratio(pair) -> str:
  return f'{pair[0]}/{pair[1]}'


def markdown(report: dict) -> str:
  c = report['correlation']
  lines = [f"# Objective diagnostics: {report['workdir']} (step {report['step']})", '',
           f"Spearman rank correlation of J with Monte Carlo returns, {c['windows']} windows of "
           'held-out dataset episodes: dynamics-model rollout '
           f"{c['spearman_model']:.3f}, encoder latents {c['spearman_encoder']:.3f}.", '',
           '| K | actor-prior candidates | held-out success | 95% CI | vs largest K '
           '(only this K / only largest) | p | decisions departing from the actor prior | '
           'success of episodes with / without departures |',
           '| ---: | ---: | --- | --- | --- | ---: | ---: | --- |']
  for r in report['success_by_k']:
    m = r['vs_largest_k']
    lines.append(f"| {r['k']} | {r['prior']} | {r['successes']}/{r['episodes']} = "
                 f"{r['success_rate']:.2f} | [{r['success_ci95'][0]:.2f}, "
                 f"{r['success_ci95'][1]:.2f}] | {m['a_only']} / {m['b_only']} | "
                 f"{m['p_value']:.2g} | {r['departure_share']:.2f} | "
                 f"{_ratio(r['success_with_departures'])} / "
                 f"{_ratio(r['success_without_departures'])} |")
  wins = ', '.join(f'{k} {v:.2f}' for k, v in report['candidate_wins'].items())
  lines += ['', f'Winning candidate kinds (K = {report["k"]}, planning from the windows\' start '
            f'states): {wins}.', '']
  return '\n'.join(lines)


class _Recorder:
  """An environment of `envs.make_env` that keeps each step's reward and scalar `info` terms
  in `self.steps` (a new list per reset, also appended to `log`)."""

  def __init__(self, log: list, **kwargs):
    from ld_mpc_jax import envs  # pylint: disable=g-import-not-at-top
    self.env, self.log, self.steps = envs.make_env(**kwargs), log, []

  def reset(self, **kwargs):
    self.steps = []
    self.log.append(self.steps)
    return self.env.reset(**kwargs)

  def step(self, action):
    obs, reward, terminated, truncated, info = self.env.step(action)
    terms = {k: float(v) for k, v in info.items()
             if np.isscalar(v) and not isinstance(v, (str, bool))}
    self.steps.append(dict(terms, reward=float(reward)))
    return obs, reward, terminated, truncated, info

  def render(self):
    return self.env.render()


def summarize_trace(steps, last: int = 50) -> dict:
  """One episode's per-decision dicts (reward and info terms) -> decisions, return, largest
  reward, mean reward of the last `last` decisions, and per info term its last and largest
  value (`TERM_last`, `TERM_max`)."""
  if not steps:
    raise ValueError('summarize_trace needs at least one step')
  reward = np.array([s['reward'] for s in steps])
  out = dict(decisions=len(steps), ret=float(reward.sum()), max_reward=float(reward.max()),
             mean_reward_last=float(reward[-last:].mean()))
  for term in sorted(k for k in steps[0] if k not in ('reward', 'success', 'env_steps')):
    values = np.array([s.get(term, np.nan) for s in steps])
    out[f'{term}_last'], out[f'{term}_max'] = float(values[-1]), float(np.nanmax(values))
  return out


def trace_episodes(spec: EvalSpec, params, mode: str, indices, seed: int, num_episodes: int,
                   policy_name: str) -> list:
  """Rows of `summarize_trace` (with success, first_success, episode, policy) for episodes
  `indices` of the held-out list of evaluation seed `seed`, run by `mode` in lockstep."""
  log = []
  records = evaluation_suite.evaluate_policy(
      spec, params, mode, num_episodes, seed, batch_size=len(indices), only=indices,
      env_factory=lambda **kw: _Recorder(log, **kw))['records']
  return [dict(policy=policy_name, episode=i, success=int(r['success']),
               first_success=r['first_success'], **summarize_trace(steps))
          for i, r, steps in zip(indices, records, log[-len(indices):])]


def trace_markdown(rows) -> str:
  """One table row per policy and episode: success, decisions and the reward terms."""
  if not rows:
    return ''
  terms = [k for k in rows[0] if k.endswith('_last') and k != 'mean_reward_last']
  head = (['episode', 'policy', 'success (decision)', 'decisions', 'return', 'largest reward',
           'mean reward, last 50'] + [f'{t[:-5]}: last / largest' for t in terms])
  lines = ['| ' + ' | '.join(head) + ' |', '|' + ' --- |' * len(head)]
  for r in sorted(rows, key=lambda r: (r['episode'], r['policy'])):
    success = f"yes ({r['first_success']})" if r['success'] else 'no'
    cells = [str(r['episode']), r['policy'], success, str(r['decisions']), f"{r['ret']:.0f}",
             f"{r['max_reward']:.2f}", f"{r['mean_reward_last']:.2f}"]
    cells += [f"{r[t]:.2f} / {r[t[:-5] + '_max']:.2f}" for t in terms]
    lines.append('| ' + ' | '.join(cells) + ' |')
  return '\n'.join(lines) + '\n'


def gain_parts(act: ActSettings, nets, draws: int = 8):
  """parts(params, z [D], sequence [H, A], key) -> (rewards [2], values [2]): for the executed
  sequence (0) and the actor prior acting along its own rollout (1), the discounted reward sum
  over the horizon, sum_i gamma^i r_i, and gamma^H times the value members' mean at z_H, each
  averaged over `draws` fresh dynamics rollouts. rewards + values is J at pessimism 0."""
  m = act.model
  gamma, h = m.gamma, m.horizon
  roll = planner.make_rollout(m, dataclasses.replace(act.plan, num_prior_candidates=1), nets)
  members = objective.get(m).make_members(m, nets)

  def one(params, z, sequence, key):
    acts, lats = roll(params, z, sequence[None], key)  # [2, H, A], [2, H+1, D].
    r_logits, v_logits = nets.objective.apply({'params': params['objective']}, lats, acts)
    rewards = two_hot_decode(r_logits, m.vmin, m.vmax)  # [2, H]
    reward_part = discounted_return(rewards, jnp.zeros(rewards.shape[:-1]), gamma)
    value_part = gamma ** h * jnp.mean(members(params, lats, v_logits), axis=0)
    return reward_part, value_part

  def parts(params, z, sequence, key):
    r, v = jax.vmap(lambda k: one(params, z, sequence, k))(jax.random.split(key, draws))
    return r.mean(0), v.mean(0)

  return parts


class _GainPolicy:
  """The planner on one episode at a time (the per-environment key schedule of
  agent.BatchAgentPolicy, so the decisions are the evaluation's), recording the gain parts of
  each decision that departs from the actor prior."""

  def __init__(self, settings: ActSettings, params, key_seed: int, draws: int):
    nets = models.build_networks(settings.model)
    self.params, self.key_seed = params, key_seed
    self.act, self.warm = agent.make_act(settings, 'plan'), agent.uses_prev(settings.plan, 'plan')
    self.parts = jax.jit(gain_parts(settings, nets, draws))
    self.rows = []

  def start(self, episodes):
    self.key = agent.episode_keys(self.key_seed, [episodes[0].reset_seed])[0]
    self.prev = None

  def __call__(self, obs, t, active):
    obs = jnp.asarray(obs[0], jnp.float32)
    action, carry, info = self.act(self.params, obs, self.key, t, self.prev)
    self.prev = carry if self.warm else None
    sequence = carry[0] if isinstance(carry, tuple) else carry  # (sequence, Guard) with one.
    row = dict(t=int(t), departed=bool(np.asarray(info)[2]))
    if row['departed']:
      r, v = self.parts(self.params, models.encode(self.params, obs), sequence,
                        jax.random.fold_in(jax.random.fold_in(self.key, t), 77_001))
      row.update(reward_gain=float(r[0] - r[1]), value_gain=float(v[0] - v[1]),
                 j_prior=float(r[1] + v[1]))
    self.rows.append(row)
    return np.asarray(action)[None]


def departure_gains(spec: EvalSpec, params, indices, seed: int, num_episodes: int,
                    draws: int = 8) -> list:
  """For episodes `indices` of the held-out list of evaluation seed `seed`, run by the planner of
  `spec`: one dict per decision (t, departed, the environment's reward and info terms, and for
  departures reward_gain, value_gain: the executed sequence's parts of J minus the actor
  prior's, `gain_parts`, and j_prior), grouped as [dict(episode, success, first_success,
  decisions=[...])]."""
  e = spec.eval
  policy = _GainPolicy(spec.act, params, seed if e.key_seed < 0 else e.key_seed, draws)
  eps = evaluation_suite.episodes(spec.goals, 'held_out', seed, num_episodes)
  out = []
  for i in indices:
    log, policy.rows = [], []
    records, _ = evaluation.run_episodes(
        policy, [eps[i]], spec.task, batch_size=1, action_repeat=e.action_repeat,
        max_episode_steps=e.max_episode_steps, env_factory=lambda **kw: _Recorder(log, **kw),
        progress=False)
    steps = log[-1]
    decisions = [dict(row, **steps[row['t']]) for row in policy.rows]
    out.append(dict(episode=i, success=int(records[0]['success']),
                    first_success=records[0]['first_success'], decisions=decisions))
  return out


def summarize_gains(episode: dict) -> dict:
  """One `departure_gains` episode -> decisions, departure share, and over its departures: the
  mean reward and value gains, the share of departures whose value gain exceeds their reward
  gain, the median gain relative to the actor prior's J, and the share of departures whose gain
  is negative on the fresh rollouts (`reversed`; NaN without departures)."""
  rows = episode['decisions']
  dep = [r for r in rows if r['departed']]
  out = dict(episode=episode['episode'], success=episode['success'],
             first_success=episode['first_success'], decisions=len(rows),
             departure_share=len(dep) / max(len(rows), 1))
  if not dep:
    return dict(out, reward_gain=float('nan'), value_gain=float('nan'),
                value_led=float('nan'), relative_gain=float('nan'), reversed=float('nan'))
  r = np.array([d['reward_gain'] for d in dep])
  v = np.array([d['value_gain'] for d in dep])
  rel = (r + v) / np.maximum(np.abs([d['j_prior'] for d in dep]), 1e-6)
  return dict(out, reward_gain=float(r.mean()), value_gain=float(v.mean()),
              value_led=float(np.mean(v > r)), relative_gain=float(np.median(rel)),
              reversed=float(np.mean(r + v < 0)))


def gains_markdown(summaries) -> str:
  """One table row per `summarize_gains` summary."""
  head = ['episode', 'success (decision)', 'decisions', 'departing', 'mean reward gain',
          'mean value gain', 'departures led by the value', 'median gain / J of the actor prior',
          'departures reversed on fresh rollouts']
  lines = ['| ' + ' | '.join(head) + ' |', '|' + ' --- |' * len(head)]
  for s in summaries:
    success = f"yes ({s['first_success']})" if s['success'] else 'no'
    lines.append(f"| {s['episode']} | {success} | {s['decisions']} | "
                 f"{s['departure_share']:.2f} | {s['reward_gain']:.2f} | {s['value_gain']:.2f} | "
                 f"{s['value_led']:.2f} | {s['relative_gain']:.4f} | {s['reversed']:.2f} |")
  return '\n'.join(lines) + '\n'
