"""Named planner settings for `--variant=NAME` (`experiments.evaluate selection`, `diagnose trace`,
`diagnose departures`): each a set of dotted config overrides, values as a command line gives them.
`--variant=NAME:field=value,...` still defines one inline."""

VARIANTS = {
    # The planner as it ships: the argmax of J over every candidate.
    'argmax': {},
    # Safe selection with its recommended gates, the fields' defaults for runs trained since
    # config version 1 (docs/results.md, Summary).
    'safe': {'plan.safe_selection': 'True'},
    # The same setting spelled out, for runs saved before: they keep the gate values they saved.
    'safe_full': {'plan.safe_selection': 'True', 'plan.safe_margin': '2',
                  'plan.safe_margin_scaling': 'expected_max', 'plan.safe_confirm': 'True',
                  'plan.confirm_draws': '8', 'plan.confirm_margin': '1',
                  'plan.fallback_drop': '0.1', 'plan.fallback_floor': '1000'},
    # The proposal's and the actor prior's candidates only: no Gaussian round, no refinement
    # (how the online presets evaluate).
    'nogauss_norefine': {'plan.num_gaussian': '0', 'plan.iterations': '0'},
}
