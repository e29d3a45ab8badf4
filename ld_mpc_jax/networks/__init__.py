"""Plain flax building blocks."""
from ld_mpc_jax.networks.mlp import MLP
from ld_mpc_jax.networks.transformer import (SelfAttention, TimeEmbedding, Transformer,
                                             TransformerBlock, fourier_features,
                                             position_embedding)
