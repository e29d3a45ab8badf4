"""One checkpoint's held-out episodes under several planner and actor-prior settings: the
evaluation behind `experiments.evaluate selection` (a module without flags, so that tests and
other launchers can import it)."""

from ld_mpc_jax.configs import overrides


def evaluate_run(workdir: str, variants, baselines, episodes: int, seed: int,
                 only_tasks=None, actor_variants=()) -> list:
  """Records of every variant ('plan[NAME]'), baseline and actor variant ('actor[NAME]') on one
  checkpoint's held-out episodes (of the tasks in `only_tasks` alone, for a multi-task
  checkpoint, if given)."""
  import functools
  from ld_mpc_jax.runs import checks as run_checks
  from ld_mpc_jax.eval import multitask_eval
  from ld_mpc_jax.eval.spec import EvalSpec
  from ld_mpc_jax.model.config_checks import check_config
  config, params, step = run_checks.load_for_evaluation(workdir)  # --tasks checked in main.
  records = []
  runs = [(f'plan[{name}]', 'plan', overrides.with_overrides(config, items))
          for name, items in variants]
  runs += [(mode, mode, config) for mode in baselines]
  runs += [(f'actor[{name}]', 'actor', overrides.with_overrides(config, items))
           for name, items in actor_variants]
  for policy, mode, cfg in runs:
    check_config(cfg)
    spec = EvalSpec.from_config(cfg)
    _, evaluate = multitask_eval.grid(spec, ('held_out',))
    if only_tasks:
      evaluate = functools.partial(evaluate, only=tuple(only_tasks))
    recs = evaluate(spec, params, workdir, step, (mode,), ('held_out',), (seed,), episodes,
                    run=workdir)
    for r in recs:  # The training seed lets compare_sweeps pair two configs' checkpoints.
      r.update(policy=policy, train_seed=int(config.seed))
    records.extend(recs)
  return records
