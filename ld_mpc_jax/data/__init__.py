"""Offline data: scripted-policy collection, dataset files, TD-MPC2, replay."""

from ld_mpc_jax.data.collection import collect
from ld_mpc_jax.data.collection import get_or_collect
from ld_mpc_jax.data.collection import PRESETS
from ld_mpc_jax.data.collection import summary
from ld_mpc_jax.data.dataset import Dataset
from ld_mpc_jax.data.dataset import DatasetError
from ld_mpc_jax.data.dataset import FORMAT_VERSION
from ld_mpc_jax.data.dataset import load
from ld_mpc_jax.data.dataset import save
from ld_mpc_jax.data.multitask import make_buffer
from ld_mpc_jax.data.multitask import TaskBalancedBuffer
from ld_mpc_jax.data.replay import ReplayBuffer
from ld_mpc_jax.data.replay import window_length
from ld_mpc_jax.data.sources import DataSpec
from ld_mpc_jax.data.sources import load_dataset
from ld_mpc_jax.data.sources import SOURCES
from ld_mpc_jax.data.tdmpc2 import load_tdmpc2
from ld_mpc_jax.data.tdmpc2 import TASK_SETS

__all__ = [
    'collect', 'get_or_collect', 'PRESETS', 'summary', 'Dataset',
    'DatasetError', 'FORMAT_VERSION', 'load', 'save', 'ReplayBuffer',
    'load_tdmpc2', 'TASK_SETS', 'DataSpec', 'load_dataset', 'SOURCES', 'make_buffer',
    'TaskBalancedBuffer', 'window_length',
]
