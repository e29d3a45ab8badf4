"""Environment suites (`suite.Suite`, registry `SUITES`); Meta-World is the one registered.

`SUITE` is the suite this project runs on; the names below are its parts, for the callers
(data collection, evaluation, online acting) that need no more of it.
"""

from ld_mpc_jax.envs import goals, metaworld_env
from ld_mpc_jax.envs.suite import Suite, SUITES

SUITE = SUITES.register('metaworld', Suite(
    name='metaworld', make_env=metaworld_env.make_env, task_names=metaworld_env.task_names,
    check_task=metaworld_env.check_task, scripted_policy=metaworld_env.scripted_policy,
    episode_seeds=metaworld_env.episode_seeds, goal_splits=goals.SPLITS,
    make_episodes=goals.make_episodes, dataset_goal_vectors=goals.dataset_goal_vectors,
    train_goals=lambda task, seed: goals.mt1_goals(task, seed),
    obs_dim=metaworld_env.OBS_DIM, act_dim=metaworld_env.ACT_DIM,
    max_episode_steps=metaworld_env.METAWORLD_MAX_PATH_LENGTH,
    packages=('metaworld', 'mujoco'), scripted_source='metaworld-scripted'))

ACT_DIM = SUITE.act_dim
OBS_DIM = SUITE.obs_dim
MAX_EPISODE_STEPS = SUITE.max_episode_steps
check_task = SUITE.check_task
episode_seeds = SUITE.episode_seeds
make_env = SUITE.make_env
scripted_policy = SUITE.scripted_policy
task_names = SUITE.task_names

__all__ = [
    'ACT_DIM', 'check_task', 'episode_seeds', 'goals', 'make_env', 'MAX_EPISODE_STEPS',
    'OBS_DIM', 'scripted_policy', 'Suite', 'SUITE', 'SUITES', 'task_names',
]
