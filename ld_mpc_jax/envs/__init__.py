"""Meta-World gymnasium environments."""

from ld_mpc_jax.envs.metaworld_env import ACT_DIM
from ld_mpc_jax.envs.metaworld_env import check_task
from ld_mpc_jax.envs.metaworld_env import episode_seeds
from ld_mpc_jax.envs.metaworld_env import make_env
from ld_mpc_jax.envs.metaworld_env import METAWORLD_MAX_PATH_LENGTH
from ld_mpc_jax.envs.metaworld_env import MetaWorldWrapper
from ld_mpc_jax.envs.metaworld_env import OBS_DIM
from ld_mpc_jax.envs.metaworld_env import scripted_policy
from ld_mpc_jax.envs.metaworld_env import task_names

__all__ = [
    'ACT_DIM', 'check_task', 'episode_seeds', 'make_env', 'METAWORLD_MAX_PATH_LENGTH',
    'MetaWorldWrapper', 'OBS_DIM', 'scripted_policy', 'task_names',
]
