"""ld_mpc_jax.runs.loop: the shared loop checkpoints and evaluates at the same crossings for any job."""

import os

import pytest

from ld_mpc_jax.configs import door_open
from ld_mpc_jax.learn import checkpointing
from ld_mpc_jax.eval import run_files
from ld_mpc_jax.runs import loop as runs
from ld_mpc_jax.runs.seed_plan import seed_plans


@pytest.mark.parametrize('before,after,every,expected', [
    (0, 1, 5, False), (4, 5, 5, True), (5, 6, 5, False), (38, 42, 40, True), (40, 80, 40, True),
    (41, 79, 40, False)])
def test_crossed(before, after, every, expected):
  assert runs.crossed(before, after, every) == expected


class _Job:
  """Advances by `step` units; records what the loop asked of it."""

  def __init__(self, step, start=0):
    self.progress, self.step, self.calls = start, step, []

  def advance(self):
    self.progress += self.step

  def log(self, before):
    self.calls.append(('log', before, self.progress))

  def checkpoint(self):
    self.calls.append(('checkpoint', self.progress))

  def eval_params(self):
    return 'params'


class _Run:
  def __init__(self, last_eval=-1):
    self.evals, self.last_eval = [], last_eval

  def periodic_eval(self, params, step, missing_since=None):
    if missing_since is None or self.last_eval < missing_since:
      self.evals.append((params, step))


def test_loop_checkpoints_at_crossings_and_the_end_and_evaluates_before_the_end():
  run, job = _Run(), _Job(step=40)  # Waves of 40 environment steps, as the online smoke run.
  runs.loop(run, job, total=200, checkpoint_every=80, eval_every=100)
  assert [c for c in job.calls if c[0] == 'checkpoint'] == [
      ('checkpoint', 80), ('checkpoint', 160), ('checkpoint', 200)]
  assert [c[1:] for c in job.calls if c[0] == 'log'] == [
      (0, 40), (40, 80), (80, 120), (120, 160), (160, 200)]
  assert run.evals == [('params', 120)]  # 200 is the final evaluation's, not the loop's.


def test_loop_resumed_at_the_end_does_nothing():
  run, job = _Run(), _Job(step=1, start=10)
  runs.loop(run, job, total=10, checkpoint_every=5, eval_every=5)
  assert job.calls == [] and run.evals == []


def test_a_run_killed_during_the_evaluation_after_its_checkpoint_makes_it_when_resumed():
  """Checkpointed at 120, killed while evaluating 120: resumed, it evaluates 120 first; one whose
  evaluation of 100 is logged goes on (the next is at 200)."""
  run, job = _Run(last_eval=0), _Job(step=40, start=120)
  runs.loop(run, job, total=240, checkpoint_every=40, eval_every=100)
  assert run.evals == [('params', 120), ('params', 200)]
  run, job = _Run(last_eval=120), _Job(step=40, start=120)
  runs.loop(run, job, total=240, checkpoint_every=40, eval_every=100)
  assert run.evals == [('params', 200)]


def test_a_run_skips_the_catch_up_evaluation_it_has_logged(tmp_path, monkeypatch):
  run = runs.Run(seed_plans(door_open.get_config('smoke'), str(tmp_path))[0])
  assert run.last_eval_step() == -1
  for step in (0, 100):
    run_files.append_csv(os.path.join(str(tmp_path), runs.EVAL_CSV), dict(step=step))
  assert run.last_eval_step() == 100
  made = []
  monkeypatch.setattr(runs, 'run_evaluation', lambda *a, **k: made.append(a) or 'result')
  monkeypatch.setattr(run, 'log_eval', lambda step, result: None)
  assert run.periodic_eval('params', 120, missing_since=100) is None and not made
  assert run.periodic_eval('params', 220, missing_since=200) == 'result' and len(made) == 1


def test_checkpoint_comes_before_the_evaluation_of_the_same_step():
  order = []
  run, job = _Run(), _Job(step=1)
  job.checkpoint = lambda: order.append('checkpoint')
  run.periodic_eval = lambda params, step: order.append('eval')
  runs.loop(run, job, total=3, checkpoint_every=2, eval_every=2)
  assert order == ['checkpoint', 'eval', 'checkpoint']


def test_a_resumed_run_drops_log_rows_written_after_its_checkpoint(tmp_path, monkeypatch):
  workdir = str(tmp_path)
  run = runs.Run(seed_plans(door_open.get_config('smoke'), workdir)[0])
  for step in (40, 80, 120):  # A run killed at 120, its last checkpoint at 80.
    run_files.append_csv(os.path.join(workdir, runs.EVAL_CSV), dict(step=step, success_rate=0.5))
    run_files.append_csv(os.path.join(workdir, run_files.METRICS_CSV), dict(step=step, loss=1.0))
    run_files.append_csv(os.path.join(workdir, run_files.ONLINE_CSV), dict(env_steps=step))
    run_files.append_csv(os.path.join(workdir, run_files.LOSSES_CSV), dict(env_steps=step))
  monkeypatch.setattr(checkpointing, 'restore_intact',
                      lambda manager, target, usable: (80, 'state', []))
  assert run.restore() == 'state'
  for name in (runs.EVAL_CSV, run_files.METRICS_CSV):
    assert [r['step'] for r in run_files.read_csv(os.path.join(workdir, name))] == ['40', '80']
  for name in (run_files.ONLINE_CSV, run_files.LOSSES_CSV):
    assert [r['env_steps'] for r in run_files.read_csv(os.path.join(workdir, name))] == [
        '40', '80']
  # No checkpoint (none saved yet, or all damaged and moved aside): the run starts over, and the
  # rows of the attempt before it go, so that they are not written twice.
  monkeypatch.setattr(checkpointing, 'restore_intact',
                      lambda manager, target, usable: (None, None, []))
  run_files.append_csv(os.path.join(workdir, run_files.ONLINE_CSV), dict(env_steps=120))
  assert run.restore() is None
  assert run_files.read_csv(os.path.join(workdir, run_files.ONLINE_CSV)) == []
