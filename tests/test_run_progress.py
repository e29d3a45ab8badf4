"""ld_mpc_jax.runs.progress: the ETA leaves out the compiling first step and counts the
evaluations left; stage lines go to stderr unless quiet."""

from ld_mpc_jax.runs import progress


def test_eta_leaves_out_compilation_and_counts_the_evaluations_left():
  eta = progress.Eta(total=1000, eval_every=250)
  assert eta.text(0) == 'eta: after the first steps'
  eta.advanced(100, seconds=600.0)  # The first advance compiles: not part of the rate.
  assert eta.text(100) == 'eta: after the first steps'
  eta.advanced(200, seconds=10.0)  # 100 steps in 10 s.
  # 800 steps left at 10 steps/s = 80 s, and the evaluations are not timed yet.
  assert eta.text(200) == 'eta 1 min + evaluations'
  eta.evaluated(60.0)
  # 80 s of steps + 3 evaluations left at 60 s (at 250 is past: 500, 750, and the final one).
  assert eta.text(300) == f'eta {round((700 / 10 + 3 * 60) / 60)} min'
  long = progress.Eta(total=10 ** 6, eval_every=10 ** 6)
  long.advanced(1, 1.0)
  long.advanced(2, 1.0)
  long.evaluated(0.0)  # eval.episodes = 0: its evaluations take no time.
  assert long.text(2) == 'eta 277.8 h'


def test_stage_lines_go_to_stderr_unless_quiet(capsys):
  progress.stage('data: 3 episodes')
  assert capsys.readouterr().err == 'data: 3 episodes\n'
  progress.QUIET.set()
  try:
    progress.stage('evaluating at step 4')
    assert capsys.readouterr().err == ''
  finally:
    progress.QUIET.clear()


def test_eta_of_an_online_run_starts_after_its_seed_waves():
  """Random seed waves step far faster than the planner's: not the run's rate."""
  eta = progress.Eta(total=10_000, eval_every=10_000, warm_from=1600)
  for after in (800, 1600):
    eta.advanced(after, seconds=1.0)  # Random waves.
  eta.advanced(2400, seconds=300.0)  # The first planner wave compiles.
  assert eta.text(2400) == 'eta: after the first steps'
  eta.advanced(3200, seconds=80.0)  # 800 steps in 80 s.
  assert eta.text(3200) == f'eta {round(6800 * 0.1 / 60)} min + evaluations'


def test_the_bars_rate_says_timing_until_measured():
  assert progress.rate_text(float('nan')) == 'timing'  # The first interval: compilation.
  assert progress.rate_text(2.345) == '2.35'
