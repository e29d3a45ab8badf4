"""ld_mpc_jax.runs.online at smoke size: exploration noise only when acting; bad configs through the
launcher. (The acting settings: tests/test_exploration.py and tests/test_config_checks.py.)

The launched smoke runs (buffer, checkpoints, SIGKILL and resume) are tests/e2e/test_online_runs.py.
"""

import csv
import json
import math
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ld_mpc_jax.configs import door_open_online
from ld_mpc_jax.eval import evaluation_suite, run_files
from ld_mpc_jax.eval.spec import GoalSource
from ld_mpc_jax.plan.search import CANDIDATE_KINDS
from ld_mpc_jax.runs import online, train
from ld_mpc_jax.data import online_buffer
from ld_mpc_jax.runs.seed_plan import seed_plans
from ld_mpc_jax.online import learner as online_learner, seats as online_seats
from ld_mpc_jax.model.models import init_params
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.online.settings import OnlineSettings
from ld_mpc_jax.plan.planner import build_plan, make_plan

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _record_policies(config, workdir, monkeypatch):
  """Runs the seed wave and one acting wave; returns (acting or evaluating, mode, candidate
  noise stds) of every policy built."""
  config.online.env_steps = 80  # The seed wave and one acting wave.
  config.online.eval_every = 40
  config.eval.splits = ('held_out',)
  config.eval.baselines = ()
  used = []

  def recording(where, original):
    def make(cfg, params, mode='plan', **kwargs):
      used.append((where, mode, cfg.plan.action_noise_std, cfg.plan.prior_noise_std))
      return original(cfg, params, mode, **kwargs)
    return make
  monkeypatch.setattr(online_seats, 'BatchAgentPolicy',
                      recording('act', online_seats.BatchAgentPolicy))
  monkeypatch.setattr(evaluation_suite, 'BatchAgentPolicy',
                      recording('eval', evaluation_suite.BatchAgentPolicy))
  # No learning needed here: an update that only counts (and compiles in no time).
  monkeypatch.setattr(online_learner, 'make_seeds_update', lambda learn, n, per_call: (
      lambda state, batch, keys: (state.replace(step=state.step + 1),
                                  {'loss': jnp.ones(n, jnp.float32)})))
  train.train_and_evaluate(config, workdir)
  return used


def test_actor_prior_acts_alone_and_the_planner_still_evaluates(tmp_path, monkeypatch):
  config = door_open_online.get_config('smoke')
  config.online.act_mode = 'actor'
  used = _record_policies(config, str(tmp_path / 'run'), monkeypatch)
  assert {u[1] for u in used if u[0] == 'act'} == {'actor'}
  assert 'plan' in {u[1] for u in used if u[0] == 'eval'}
  # online.csv says who acted; no decision was planned, so the planner's shares are unmeasured.
  with open(tmp_path / 'run' / 'online.csv') as f:
    rows = list(csv.DictReader(f))
  assert [r['acting'] for r in rows] == ['random', 'actor']
  assert math.isnan(float(rows[1]['won_proposal'])) and math.isnan(float(rows[1]['departed']))
  # Every stored episode starts at its own reset observation (not at a later one written into
  # the same array), in the random wave and the acting wave alike.
  from ld_mpc_jax import data, envs  # pylint: disable=g-import-not-at-top
  buffer = data.load(online_buffer.buffer_path(str(tmp_path / 'run'), 80))
  seeds = envs.episode_seeds(config.seed, buffer.num_episodes, 'online')
  assert buffer.num_episodes == 4
  env = envs.make_env(config.task, seed=config.data.seed,
                      action_repeat=config.eval.action_repeat,
                      max_episode_steps=config.online.episode_steps)
  for i, s in enumerate(seeds):
    first = buffer.episode(i)['obs']
    assert np.allclose(first[0], env.reset(seed=int(s))[0], atol=1e-6)
    assert not np.allclose(first[0], first[-1])


def test_any_task_by_flag_explores_only_while_acting(tmp_path, monkeypatch):
  """One smoke run checks both: exploration noise only on the acting planner (none in
  evaluation), and --config.task with online.train_goals='random': the acting environments draw
  fresh goal configurations of that task, the evaluation ones keep its held-out goals."""
  from ld_mpc_jax import envs  # pylint: disable=g-import-not-at-top
  made = []
  original = envs.make_env
  def recording(task, *args, **kwargs):
    made.append((task, kwargs.get('random_goals', False)))
    return original(task, *args, **kwargs)
  monkeypatch.setattr(envs, 'make_env', recording)
  config = door_open_online.get_config('smoke')
  config.task, config.online.train_goals = 'push-v3', 'random'
  used = _record_policies(config, str(tmp_path / 'run'), monkeypatch)
  # Exploration noise: on every acting planner, on no evaluating one.
  assert ('act', 'plan', 0.2, 0.2) in used
  evaluations = [u for u in used if u[0] == 'eval']
  assert evaluations and all(u[2:] == (0.0, 0.0) for u in evaluations)
  assert all(u[2:] == (0.2, 0.2) for u in used if u[0] == 'act')
  # The acting planner's candidates are the plain planner's plus noise, same key and params.
  acting = OnlineSettings.from_config(config).acting_plan(PlanSettings.from_config(config))
  params = init_params(config, jax.random.key(0))
  z = jax.random.normal(jax.random.key(1), (config.model.latent_dim,))
  noisy = build_plan(ModelSettings.from_config(config), acting)(params, z, jax.random.key(2))
  plain = make_plan(config)(params, z, jax.random.key(2)).candidates
  assert config.plan.action_noise_std == 0.0 and acting.action_noise_std == 0.2
  noisy = noisy.candidates
  assert float(jnp.abs(noisy - plain).max()) > 0.05
  assert float(jnp.abs(noisy).max()) <= 1.0
  # The task by flag: acting and evaluation alike on push-v3.
  assert made and {task for task, _ in made} == {'push-v3'}
  assert made[:config.online.num_envs] == [('push-v3', True)] * config.online.num_envs
  assert not any(random for _, random in made[config.online.num_envs:])
  with open(tmp_path / 'run' / 'report.json') as f:
    assert '"task": "push-v3"' in f.read()
  from ld_mpc_jax import data  # pylint: disable=g-import-not-at-top
  buffer = data.load(online_buffer.buffer_path(str(tmp_path / 'run'), 80))
  starts = np.stack([envs.metaworld_env.goal_vector(buffer.episode(i)['obs'][0])
                     for i in range(buffer.num_episodes)])
  _, mt1 = envs.goals.mt1_goals('push-v3', config.data.seed)
  assert not envs.goals.matches(starts, mt1).any()  # None of the 50 goals of the MT1 seed.
  vectors, mt1_seed = evaluation_suite.dataset_goals(  # No train split to evaluate.
      GoalSource.from_config(config))
  assert vectors.shape == (0, 6) and mt1_seed is None


@pytest.mark.parametrize('override,match', [
    ('--config.online.init_from=/nonexistent/run', 'init_from'),
    ('--config.online.update_ratio=-1', 'update_ratio'),
    ('--config.online.seed_steps=0', 'seed_steps'),
    ('--config.online.act_mode=proposal', 'act_mode'),
])
def test_bad_online_config_exits_2_with_one_line(tmp_path, override, match):
  done = subprocess.run([sys.executable, '-m', 'experiments.train',
                         '--config=door_open_online.py:smoke', f'--workdir={tmp_path}', override],
                        cwd=REPO, capture_output=True, text=True, timeout=120)
  assert done.returncode == 2
  lines = done.stderr.strip().splitlines()
  assert len(lines) == 1 and lines[0].startswith('error:') and match in lines[0]


def test_fine_tuning_from_a_run_of_another_task_is_refused_naming_the_flag(tmp_path):
  from ld_mpc_jax.learn import checkpointing  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.configs import door_open  # pylint: disable=g-import-not-at-top
  offline = door_open.get_config('smoke')
  offline.task = 'push-v3'
  checkpointing.save_config(offline, str(tmp_path / 'push_run'))
  config = door_open_online.get_config('smoke')
  config.online.init_from = str(tmp_path / 'push_run')
  with pytest.raises(ValueError, match=r'trained on push-v3, not door-open-v3: pass '
                     r'--config.task=push-v3'):
    online.check_init_from(seed_plans(config, ''))


class _Stop(Exception):
  """Stands in for the run itself: the test ends where the work would start."""


@pytest.mark.parametrize('ratio,warnings', [(0.0, 1), (1.0, 0)])
def test_update_ratio_zero_warns_once_before_the_work(tmp_path, monkeypatch, capsys, ratio,
                                                      warnings):
  config = door_open_online.get_config('smoke')
  config.online.update_ratio = ratio
  def stop(*args):
    raise _Stop
  monkeypatch.setattr(online.runs, 'Run', stop)
  with pytest.raises(_Stop):
    train.train_and_evaluate(config, str(tmp_path / 'run'))
  lines = [l for l in capsys.readouterr().err.splitlines() if l.startswith('warning:')]
  assert len(lines) == warnings
  if warnings:
    assert lines[0] == ('warning: config.online.update_ratio=0: no updates; the agent is '
                        'evaluated as it starts (untrained)')


def _rows(path):
  with open(path) as f:
    return list(csv.DictReader(f))


def test_acting_records_who_won_and_how_spread_the_candidates_were(tmp_path, monkeypatch):
  """One acting wave without the proposal's candidates (`online.act_proposal=False`) and with
  the annealed intrinsic term (the learned exploration value's too): online.csv says who won each planned decision, how spread the
  candidates' first actions were and the term's weights; report.json and report.md repeat it."""
  config = door_open_online.get_config('smoke')
  config.plan.num_prior_candidates, config.online.act_num_gaussian = 2, 3
  o = config.online
  o.act_proposal, o.act_schedule = False, 'linear'
  o.act_pessimism, o.act_pessimism_end, o.act_disagreement = -1.0, 0.0, 2.0
  o.act_dynamics_draws, o.act_iterations, config.plan.num_elites = 2, 1, 3
  config.loss.w_novelty, o.act_novelty, o.act_novelty_end = 1.0, 3.0, 0.0  # The exploration value.
  acting = OnlineSettings.from_config(config).acting_plan(PlanSettings.from_config(config))  # Evaluation keeps the proposal's K - P candidates.
  assert (acting.num_candidates, config.plan.num_candidates) == (2, 4)
  _record_policies(config, str(tmp_path / 'run'), monkeypatch)
  wave = _rows(tmp_path / 'run' / 'online.csv')[1]
  assert wave['acting'] == 'planner' and int(wave['planned']) == 20  # 2 envs x 10 decisions.
  won = {k: float(wave[f'won_{k}']) for k in CANDIDATE_KINDS}
  assert won['proposal'] == 0.0  # None drawn.
  assert won['actor_prior'] + won['gaussian'] + won['refined'] == pytest.approx(1.0)
  assert math.isnan(float(wave['spread_proposal']))  # No proposal candidate to spread.
  assert float(wave['elites_proposal']) == 0.0  # Nor among the elites the refinement starts from.
  assert 0.05 < float(wave['spread_first']) <= 1.0  # Actions in [-1, 1]; the Gaussians spread.
  # The first planner wave acts with the schedule's start values (seed steps: 40).
  assert (float(wave['act_pessimism']), float(wave['act_disagreement']),
          float(wave['act_novelty'])) == (-1.0, 2.0, 3.0)
  with open(tmp_path / 'run' / 'report.json') as f:
    whole = json.load(f)['acting']['whole']
  assert whole['planned'] == 20 and whole['spread_proposal'] is None
  assert whole['won_gaussian'] == pytest.approx(won['gaussian'])
  assert whole['spread_first'] == pytest.approx(float(wave['spread_first']))
  with open(tmp_path / 'run' / 'report.md') as f:
    assert f"| whole run | 20 | 0% | {won['actor_prior']:.0%} |" in f.read()


def test_acting_summary_weights_each_wave_by_its_planned_decisions(tmp_path):
  from ld_mpc_jax.runs import online_report  # pylint: disable=g-import-not-at-top
  nan = float('nan')
  waves = [dict(env_steps=800, planned=0, won_proposal=nan, won_actor_prior=nan, departed=nan,
                spread_first=nan, spread_proposal=nan),
           dict(env_steps=1600, planned=10, won_proposal=0.2, won_actor_prior=0.8, departed=0.5,
                spread_first=0.4, spread_proposal=0.1),
           dict(env_steps=2400, planned=30, won_proposal=0.6, won_actor_prior=0.4, departed=0.9,
                spread_first=0.2, spread_proposal=nan)]
  for row in waves:
    run_files.append_csv(str(tmp_path / 'online.csv'), row)
  acting = online_report.acting_summary(str(tmp_path), every=2000)
  whole = acting['whole']
  assert whole['planned'] == 40 and whole['env_steps'] == 2400
  assert whole['won_proposal'] == pytest.approx((0.2 * 10 + 0.6 * 30) / 40)
  assert whole['departed'] == pytest.approx((0.5 * 10 + 0.9 * 30) / 40)
  assert whole['spread_first'] == pytest.approx((0.4 * 10 + 0.2 * 30) / 40)
  assert whole['spread_proposal'] == pytest.approx(0.1)  # The wave without one is left out.
  assert [(s['env_steps'], s['planned']) for s in acting['spans']] == [(1600, 10), (2400, 30)]
  assert acting['spans'][0]['won_proposal'] == pytest.approx(0.2)
  lines = online_report.acting_md(acting)
  assert '| to 1,600 | 10 | 20% | 80% | 50% | 0.400 | 0.100 |' in lines
  assert '| whole run | 40 | 50% | 50% | 80% | 0.250 | 0.100 |' in lines
  # The same table from a gzipped record by `experiments.report acting`.
  import gzip, shutil  # pylint: disable=g-import-not-at-top,multiple-imports
  with open(tmp_path / 'online.csv', 'rb') as f, gzip.open(tmp_path / 'online.csv.gz', 'wb') as g:
    shutil.copyfileobj(f, g)
  out = subprocess.run([sys.executable, '-m', 'experiments.report', 'acting',
                        str(tmp_path / 'online.csv.gz'), '--every=2000'], cwd=REPO,
                       capture_output=True, text=True, check=True).stdout
  assert '| to 1,600 | 10 | 20% | 80% | 50% | 0.400 | 0.100 |' in out
  assert '| whole run | 40 | 50% | 50% | 80% | 0.250 | 0.100 |' in out


def test_planned_targets_keep_the_planners_sequences_with_the_planner_waves(tmp_path,
                                                                           monkeypatch):
  """loss.act_target='planned': the planner wave's episodes carry the planner's chosen
  sequences [L, H, A] into the buffer file (the random wave's none), each executed action is the
  first of its sequence where no noise is added, and every update's batch has plan and has_plan."""
  config = door_open_online.get_config('smoke')
  config.loss.act_target = 'planned'
  config.online.exec_noise_start = config.online.exec_noise_end = 0.0
  batches = []
  original = online_learner.make_seeds_update

  def recording(learn, n, per_call):
    update = original(learn, n, per_call)
    return lambda state, batch, keys: batches.append(sorted(batch)) or update(state, batch, keys)
  monkeypatch.setattr(online_learner, 'make_seeds_update', recording)
  config.online.env_steps, config.online.eval_every = 80, 80
  config.eval.splits, config.eval.baselines, config.eval.episodes = ('held_out',), (), 1
  train.train_and_evaluate(config, str(tmp_path / 'run'))
  from ld_mpc_jax import data  # pylint: disable=g-import-not-at-top
  buffer = data.load(online_buffer.buffer_path(str(tmp_path / 'run'), 80))
  assert buffer.episode_data['planned'].tolist() == [False, False, True, True]
  h, a = config.horizon, config.action_dim
  for e in (2, 3):
    plan = buffer.episode_data['plan'][e]
    assert plan.shape == (10, h, a) and np.abs(plan).max() <= 1.0 and np.abs(plan).max() > 0
    np.testing.assert_allclose(buffer.episode(e)['action'], plan[:, 0], atol=1e-6)
  assert not buffer.episode_data['plan'][:2].any()
  assert batches and all({'plan', 'has_plan'} <= set(keys) for keys in batches)


def test_a_wave_returns_its_steps_and_leaves_the_counters_to_the_job(tmp_path):
  """run_wave writes nothing of the job: the counters it is given stay as they were, a random
  wave asks the learner for no update, and the job adds the steps and episodes after it."""
  config = door_open_online.get_config('smoke')
  config.train.num_seeds = 2
  job = online.online_job(seed_plans(config, str(tmp_path)), None)
  job.bar.close()
  asked = []

  class Learner:  # Would be asked to catch up by a planner wave only.
    def catch_up(self, env_steps):
      asked.append(env_steps)
  counters = dict(job.steps)
  schedule = online_seats.WaveSchedule('random', 0.0)
  records, steps = online_seats.run_wave(job.seats, schedule, job.acting, job.online,
                                         job.model.action_dim, counters, Learner(), job.bar)
  o = config.online
  assert counters == job.steps == dict(env_steps=0, episodes=0, train_seconds=0.0)
  assert steps == o.num_envs * o.episode_steps and not asked
  assert [len(r.episodes) for r in records] == [o.num_envs] * 2
  assert all(len(e['action']) * job.online.action_repeat == o.episode_steps
             for r in records for e in r.episodes)
  job.advance()  # The job's own wave (the first is random too): the counters after it.
  assert (job.progress, job.counters['episodes']) == (steps, o.num_envs)
