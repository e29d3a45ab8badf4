"""How well the reward head sees rare successes (issue 70): its predicted reward on held-out
transitions against whether they solved the task.

A policy of the checkpoint (the actor prior by default) runs held-out episodes; each episode ends
at its first success, so a solved episode's last transition is its one success. For every
transition the objective predicts r_t from the window that starts at it (the causal transformer's
first position sees z_t and a_t alone; later positions are padded), decoded from its two-hot bins.
Reported: the mean predicted reward on successes and on the other transitions, the AUC (the chance
that a success is scored above another transition, ties half) and a reliability table (per bin of
predicted reward: transitions and the share that are successes).
"""

from typing import Dict, List, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ld_mpc_jax.eval import evaluation, evaluation_suite
from ld_mpc_jax.eval.spec import EvalSpec
from ld_mpc_jax.model import models
from ld_mpc_jax.model.settings import ModelSettings
from ld_mpc_jax.ops.numerics import two_hot_decode
from ld_mpc_jax.plan.agent import make_policy

BINS = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9)


def record_episodes(spec: EvalSpec, params, mode: str, num_episodes: int,
                    seed: int) -> List[Dict[str, np.ndarray]]:
  """Held-out episodes of `mode`: each a dict of obs [L, obs_dim] (before each action), action
  [L, A] and success [L] (1 on the last transition of a solved episode)."""
  policy, reset = make_policy(spec.act, params, mode, seed=0)
  episodes, current = [], {}

  def recording(obs):
    action = np.asarray(policy(obs))
    current['obs'].append(np.asarray(obs, np.float32))
    current['action'].append(action.astype(np.float32))
    return action

  def start(episode):
    if current:
      episodes.append(dict(current))
    current.update(obs=[], action=[])
    reset(episode)

  held_out = evaluation_suite.episodes(spec.goals, 'held_out', seed, num_episodes)
  records, _ = evaluation.run_episodes(evaluation.CallablePolicy(recording, start), held_out,
                                       spec.task, batch_size=1,
                                       action_repeat=spec.eval.action_repeat,
                                       max_episode_steps=spec.eval.max_episode_steps,
                                       progress=False)
  episodes.append(dict(current))
  out = []
  for ep, rec in zip(episodes, records):
    n = len(ep['action'])
    success = np.zeros(n, np.float32)
    if rec['success'] and n:
      success[-1] = 1.0
    out.append(dict(obs=np.stack(ep['obs']), action=np.stack(ep['action']), success=success))
  return out


def predicted_rewards(m: ModelSettings, params, episode) -> np.ndarray:
  """r_t for every transition of `episode` [L]: the objective's first position of the window
  that starts at t (later positions zero-padded; causal, so they do not change it), of the
  model of settings `m`."""
  nets = models.build_networks(m)
  h = m.horizon
  z = models.encode(params, episode['obs'])  # [L, D]
  pad = lambda x: jnp.concatenate([x, jnp.zeros((h + 1,) + x.shape[1:], x.dtype)])
  zp, ap = pad(z), pad(jnp.asarray(episode['action']))
  n = len(episode['action'])
  starts = jnp.arange(n)
  windows_z = jax.vmap(lambda s: jax.lax.dynamic_slice_in_dim(zp, s, h + 1))(starts)
  windows_a = jax.vmap(lambda s: jax.lax.dynamic_slice_in_dim(ap, s, h))(starts)
  r_logits, _ = nets.objective.apply({'params': params['objective']}, windows_z, windows_a)
  return np.asarray(two_hot_decode(r_logits[:, 0], m.vmin, m.vmax))


def auc(scores: Sequence[float], labels: Sequence[float]) -> float:
  """P(score of a positive > score of a negative), ties counted half; nan without both."""
  scores, labels = np.asarray(scores, np.float64), np.asarray(labels) > 0
  pos, neg = scores[labels], scores[~labels]
  if not len(pos) or not len(neg):
    return float('nan')
  greater = (pos[:, None] > neg[None]).mean()
  ties = (pos[:, None] == neg[None]).mean()
  return float(greater + 0.5 * ties)


def calibration(predicted: np.ndarray, success: np.ndarray) -> Dict[str, object]:
  """The summary of the module docstring from predicted rewards and success labels [N]."""
  edges = list(BINS) + [np.inf]
  which = np.digitize(predicted, edges[1:-1])
  table = [dict(bin=f'[{edges[i]:g}, {edges[i + 1]:g})', transitions=int((which == i).sum()),
                successes=int(success[which == i].sum())) for i in range(len(BINS))]
  pos = success > 0
  return dict(transitions=int(len(success)), successes=int(pos.sum()),
              mean_on_successes=float(predicted[pos].mean()) if pos.any() else float('nan'),
              mean_on_others=float(predicted[~pos].mean()) if (~pos).any() else float('nan'),
              auc=auc(predicted, success), reliability=table)


def markdown(summary: Dict[str, object]) -> str:
  lines = [f"{summary['transitions']} held-out transitions, {summary['successes']} of them "
           f"successes; mean predicted reward {summary['mean_on_successes']:.3f} on successes, "
           f"{summary['mean_on_others']:.3f} on the others; AUC {summary['auc']:.3f}.", '',
           '| predicted reward | transitions | successes | share |', '| --- | --- | --- | --- |']
  for row in summary['reliability']:
    share = row['successes'] / row['transitions'] if row['transitions'] else float('nan')
    lines.append(f"| {row['bin']} | {row['transitions']} | {row['successes']} | {share:.3f} |")
  return '\n'.join(lines) + '\n'
