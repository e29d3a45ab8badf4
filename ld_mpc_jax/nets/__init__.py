"""Plain flax building blocks."""
from ld_mpc_jax.nets.mlp import LATENT_NORMS, MLP, normalize_latent
from ld_mpc_jax.nets.transformer import (SelfAttention, TimeEmbedding, Transformer,
                                             TransformerBlock, fourier_features,
                                             position_embedding)
