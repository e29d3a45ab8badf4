"""LD-MPC: Latent Diffusion Model Predictive Control in JAX/Flax."""

from ld_mpc_jax.model.models import build_networks, count_params, encode, init_params
from ld_mpc_jax.model.settings import ModelSettings, PlanSettings
from ld_mpc_jax.plan.planner import PlanOutput, build_plan, make_plan
from ld_mpc_jax.learn.train_state import LearnSettings, TrainState, create_train_state, make_update
from ld_mpc_jax.runs.checks import validate_config

__all__ = ['LearnSettings', 'ModelSettings', 'PlanOutput', 'PlanSettings', 'TrainState',
           'build_networks', 'build_plan', 'count_params', 'create_train_state', 'encode',
           'init_params', 'make_plan', 'make_update', 'validate_config']
