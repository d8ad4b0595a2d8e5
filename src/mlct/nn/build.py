"""Build the networks from a Config: the one place that maps config sections to modules."""

from __future__ import annotations

from mlct.config import Config
from mlct.config_view import latent_clamp  # noqa: F401 (train/stages.py imports it here)
from mlct.errors import MlctError
from mlct.motion.features import arm_feature_columns
from mlct.nn.autoencoder import LatentAutoencoder, MotionAutoencoder
from mlct.nn.conv_autoencoder import ConvMotionAutoencoder
from mlct.nn.denoiser import Denoiser
from mlct.text.encoders import token_slots_of


AnyAutoencoder = LatentAutoencoder  # either architecture


def build_autoencoder(config: Config, feature_dim: int) -> AnyAutoencoder:
    ae = config.ae
    for option in ("arm_tokens", "bottleneck", "temporal"):
        if getattr(ae, option) and ae.architecture != "conv":
            raise MlctError(f"ae.{option} needs ae.architecture=conv")
    if ae.architecture == "conv":
        try:
            return ConvMotionAutoencoder(
                feature_dim, latent_type=ae.latent_type, n_tokens=ae.n_tokens,
                latent_dim=ae.latent_dim, levels=ae.levels, channels=ae.channels,
                max_len=config.data.max_motion_length, arm_tokens=ae.arm_tokens,
                arm_channels=ae.arm_channels, bottleneck=ae.bottleneck,
                decoder_channels=ae.decoder_channels,
                arm_decoder_channels=ae.arm_decoder_channels,
                temporal=ae.temporal, stages=ae.stages,
                arm_columns=arm_feature_columns(feature_dim) if ae.arm_tokens else None)
        except ValueError as error:
            raise MlctError(f"ae: {error}") from None
    return MotionAutoencoder(
        feature_dim, latent_type=ae.latent_type, n_tokens=ae.n_tokens,
        latent_dim=ae.latent_dim, levels=ae.levels, layers=ae.layers, heads=ae.heads,
        ff_dim=ae.ff_dim, dropout=ae.dropout, max_len=config.data.max_motion_length,
        frame_upsampler=ae.frame_upsampler)


def build_denoiser(config: Config, text_dim: int) -> Denoiser:
    d = config.denoiser
    return Denoiser(latent_dim=config.ae.latent_dim, n_tokens=config.ae.n_tokens,
                    text_dim=text_dim, width=d.width, layers=d.layers, heads=d.heads,
                    ff_dim=d.ff_dim, dropout=d.dropout,
                    text_tokens=token_slots_of(config.text.encoder),
                    condition_all_tokens=d.condition_all_tokens)


