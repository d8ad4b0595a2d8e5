"""The torch backend: the bundle's networks as PyTorch modules (mlct.nn.inference's layers),
on the CPU or a GPU, float32 or bfloat16 products."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor

from mlct.config import Config
from mlct.errors import MlctError
from mlct.generate.backends.base import Networks
from mlct.generate.bundle import ENCODER_PREFIXES
from mlct.generate.samplers import Sampler
from mlct.generate.seeds import generators_for
from mlct.io import strip_prefix
from mlct.nn.autoencoder import LatentAutoencoder
from mlct.nn.build import build_autoencoder, build_denoiser
from mlct.nn.denoiser import Denoiser
from mlct.nn.inference import for_inference, weight_dtype


class TorchNetworks(Networks):
    """The AE decoder and the denoiser as torch modules; the text encoder loaded by name.

    dtype: the precision of the networks' matrix products, "float32" (default) or "bfloat16"
    (about 1.3-1.7x faster on CPUs with AVX512-BF16, joints a few mm off fp32's:
    docs/performance.md). Either way the networks run through mlct.nn.inference's layers."""

    name = "torch"

    def __init__(self, meta: dict, tensors: dict[str, Tensor], device: Any = None,
                 dtype: str | torch.dtype = "float32") -> None:
        try:
            self.dtype = weight_dtype(dtype)
        except ValueError as err:
            raise MlctError(str(err)) from None
        super().__init__(meta, device)
        ae, denoiser = bundle_networks(self.config, meta, tensors)
        self.decoder = for_inference(ae.to(self.device), self.dtype)
        self.denoiser = for_inference(denoiser.to(self.device), self.dtype)
        self.mean = tensors["norm.mean"].float()
        self.std = tensors["norm.std"].float()

    def text_encoder(self) -> Any:
        if self._text_encoder is None:
            from mlct.text import load_text_encoder

            self._text_encoder = load_text_encoder(self.meta["text_encoder"])
        return self._text_encoder

    @torch.inference_mode()  # 4-6% faster than no_grad at batch 1 (docs/performance.md)
    def latents(self, cond: Tensor, steps: int, seed: int | Sequence[int] | None,
                guidance: float | None, uncond: Tensor | None) -> Tensor:
        return sample_loop(self.sampler, self.denoiser, self.decoder.latent_shape, cond, steps,
                           seed, guidance, uncond)

    @torch.inference_mode()
    def decode(self, z: Tensor, lengths: Sequence[int]) -> list[np.ndarray]:
        return decode_with(self.decoder, z, lengths, self.config, self.mean, self.std,
                           self.device)


def sample_loop(sampler: Sampler, denoiser: Any, latent_shape: Sequence[int], cond: Tensor,
                steps: int, seed: int | Sequence[int] | None, guidance: float | None,
                uncond: Tensor | None) -> Tensor:
    """The sampler's own loop over `denoiser` (any F(x_t, t, c) of torch tensors), from the
    seeds' noise: seed an int seeds one generator for the whole batch; a sequence seeds each
    item on its own (item i's latent is then independent of the rest of the batch)."""
    generator = generators_for(seed)
    x = sampler.noise((cond.shape[0], *latent_shape), generator)  # x_T (B, n, d)
    return sampler.sample(denoiser, x, cond, steps, generator=generator, guidance=guidance,
                          uncond=uncond)


def decode_with(decoder: Any, z: Tensor, lengths: Sequence[int], config: Config, mean: Tensor,
                std: Tensor, device: Any) -> list[np.ndarray]:
    """Stage 2's latents -> denormalized features by `decoder`, one (T_i, D) array per item."""
    lens = torch.tensor(list(lengths), device=device)
    z = z / config.schedule.latent_scale  # back to the autoencoder's latent
    feats = decoder.decode(z, lens, max(lengths))  # normalized
    feats = (feats.float().cpu() * std + mean).numpy()
    return [feats[i, :n] for i, n in enumerate(lengths)]  # numpy views: cheap per item


def bundle_networks(config: Config, meta: dict, tensors: dict[str, Tensor]
                    ) -> tuple[LatentAutoencoder, Denoiser]:
    """The bundle's AE (its decoder's weights) and denoiser as plain modules in eval mode;
    MlctError when the weights do not fit the config."""
    ae = build_autoencoder(config, meta["feature_dim"])
    missing, unexpected = ae.load_state_dict(strip_prefix(tensors, "decoder"), strict=False)
    if unexpected or any(not k.startswith(ENCODER_PREFIXES) for k in missing):
        raise MlctError("model weights do not match its config (decoder)")
    denoiser = build_denoiser(config, meta["text_dim"])
    try:
        denoiser.load_state_dict(strip_prefix(tensors, "denoiser"))
    except RuntimeError:
        raise MlctError("model weights do not match its config (denoiser)") from None
    return ae.eval().requires_grad_(False), denoiser.eval().requires_grad_(False)
