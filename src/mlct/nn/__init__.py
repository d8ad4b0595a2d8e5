"""Neural networks of mlct (no schedules, no datasets)."""

from mlct.nn.autoencoder import LATENT_TYPES, Latent, MotionAutoencoder
from mlct.nn.denoiser import Denoiser, timestep_embedding
from mlct.nn.masks import lengths_to_mask
from mlct.nn.quantize import quantize
from mlct.nn.skip_transformer import SkipTransformer

__all__ = [
    "LATENT_TYPES",
    "Denoiser",
    "Latent",
    "MotionAutoencoder",
    "SkipTransformer",
    "lengths_to_mask",
    "quantize",
    "timestep_embedding",
]
