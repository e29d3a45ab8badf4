"""Planning: make_plan -> plan(params, z, key), MPPI, and the policies that act in environments."""
