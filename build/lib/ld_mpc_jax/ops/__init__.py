"""Pure math and shared machinery: diffusion schedules and samplers, symlog and two-hot, registries, statistics, sharding, config caches and legacy fields."""
