"""Bundles of untrained networks, written as `mlct export` writes one: for the backends' tests
of what the bundled model does not use (a transformer decoder, DDIM, token conditions)."""

from __future__ import annotations

import json
from pathlib import Path

import torch

from mlct.generate.bundle import BUNDLE_FORMAT, BUNDLE_VERSION, ENCODER_KEY, ENCODER_PREFIXES


def random_bundle(path: Path, sampler: str, text_encoder: str,
                  overrides: tuple[str, ...] = ()) -> Path:
    """A bundle of untrained tiny-preset networks (transformer AE unless overridden), written as
    `mlct export` writes one."""
    from safetensors.torch import save_file

    from mlct.config import load_config
    from mlct.nn.build import build_autoencoder, build_denoiser
    from mlct.text.encoders import token_slots_of

    torch.manual_seed(0)
    config = load_config("tiny", [f"text.encoder={text_encoder}", *overrides])
    text_dim = 384 * (1 + token_slots_of(text_encoder))
    ae, denoiser = build_autoencoder(config, 263), build_denoiser(config, text_dim)
    ae_state = ae.state_dict()
    tensors = {**{f"decoder.{k}": v for k, v in ae_state.items()
                  if not k.startswith(ENCODER_PREFIXES)},
               **{f"{ENCODER_KEY}.{k}": v for k, v in ae_state.items()
                  if k.startswith(ENCODER_PREFIXES)},
               **{f"denoiser.{k}": v for k, v in denoiser.state_dict().items()},
               "norm.mean": torch.randn(263) * 0.1, "norm.std": torch.rand(263) + 0.5}
    path.mkdir(parents=True)
    save_file({k: v.contiguous() for k, v in tensors.items()}, str(path / "model.safetensors"))
    meta = {"format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "sampler": sampler, "step": 0,
            "config": config.to_dict(), "feature_dim": 263, "skeleton": "humanml3d",
            "text_encoder": text_encoder, "text_dim": text_dim}
    (path / "config.json").write_text(json.dumps(meta), encoding="utf-8")
    return path
