"""Diagnoses the planner's objective on a trained checkpoint.

  python -m experiments.diagnose --workdir=runs/door_open_cpu [--ks=1,4,16,64]

Writes <workdir>/diagnose_objective.json and .md, and prints the tables:
  1. Rank correlation (Spearman) between the planner's J and the Monte Carlo discounted return of
     windows from held-out dataset episodes: the config's task and data preset, collected with
     data seed + 1000 (goals absent from the training data). Each window is o_t and the data's
     actions a_{t:t+H}; J is computed on the dynamics model's rollout (what the planner scores)
     and on the encoder's latents of the real o_{t+1..t+H} (the objective without model error).
     Windows start at t < L - 100 so that the truncated return still covers gamma's horizon.
  2. Planner success on held-out goals for each K (the actor-prior share of the config kept;
     K = 1 is one proposal, no selection), each paired with the largest K on the same episodes
     (exact McNemar). Success that falls as K grows means the argmax exploits model error.
  3. How often each kind of candidate wins: the planner's choice at the windows' start states.
"""

import json
import os

from absl import app, flags, logging

from ld_mpc_jax.cli import errors as cli

_WORKDIR = flags.DEFINE_string('workdir', None, 'Training run directory.')
_KS = flags.DEFINE_list('ks', ['1', '4', '16', '64'], 'Candidate counts K to evaluate.')
_EPISODES = flags.DEFINE_integer('episodes', 50, 'Held-out episodes per K.')
_SEED = flags.DEFINE_integer('seed', 0, 'Evaluation seed.')
_DATA_EPISODES = flags.DEFINE_integer('data_episodes', 20, 'Held-out dataset episodes.')
_STRIDE = flags.DEFINE_integer('stride', 5, 'Decisions between window starts.')
flags.mark_flag_as_required('workdir')


def main(argv):
  del argv
  logging.set_verbosity(logging.WARNING)
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.eval.spec import EvalSpec
  from ld_mpc_jax.analysis.diagnostics import (candidate_wins, held_out_windows, markdown,
                                      objective_correlation, success_by_k)
  with cli.one_line_errors():
    ks = sorted({int(k) for k in _KS.value})
    if not ks or ks[0] < 1:
      raise ValueError(f'--ks must be integers >= 1, got {_KS.value}')
    for flag in (_EPISODES, _DATA_EPISODES, _STRIDE):
      if flag.value < 1:
        raise ValueError(f'--{flag.name} must be >= 1, got {flag.value}')
    config, params, step = run_checks.load_for_evaluation(_WORKDIR.value)
    spec = EvalSpec.from_config(config)
  obs, actions, returns = held_out_windows(spec, _DATA_EPISODES.value, _STRIDE.value)
  report = dict(workdir=_WORKDIR.value, step=step, k=spec.act.plan.num_candidates,
                correlation=objective_correlation(spec.act, params, obs, actions, returns),
                candidate_wins=candidate_wins(spec.act, params, obs[:, 0]),
                success_by_k=success_by_k(spec, params, ks, _EPISODES.value, _SEED.value))
  md = markdown(report)
  with open(os.path.join(_WORKDIR.value, 'diagnose_objective.json'), 'w') as f:
    json.dump(report, f, indent=2)
  with open(os.path.join(_WORKDIR.value, 'diagnose_objective.md'), 'w') as f:
    f.write(md)
  print(md)
