"""The model folder's critic (critic.safetensors) and best-of-N sampling with it.

A consistency model samples a motion in a few steps, so sampling N for a prompt costs one batch.
Their latents differ by seed, and for a given prompt some do what it says and some do not (on
the benchmark's test captions, 84 % of one-action motions pass their read-out checks with one
sample, 92 % with the best of eight chosen by the read-outs themselves). The critic
(nn/critic.py, trained by `mlct train critic` on the training split only) scores each latent
against the text and the pipeline decodes the best: `candidates` per prompt, the model's
default when it has a critic, 1 (plain sampling) when it does not.

    MODEL_DIR/critic.safetensors   the critic's weights (float16), its sizes and how it was
                                   trained in the safetensors metadata ("mlct": JSON)
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import torch
from safetensors import safe_open
from safetensors.torch import save
from torch import Tensor

from mlct.errors import MlctError, first_line
from mlct.io import atomic_path
from mlct.nn.critic import LatentCritic

FILE = "critic.safetensors"
FORMAT, VERSION = "mlct-critic", 1
DEFAULT_CANDIDATES = 8  # best of 8: docs/model_card.md measures 1, 4 and 8
MAX_CANDIDATES = 64


def save_critic(model_dir: str | os.PathLike, critic: LatentCritic, training: dict[str, Any],
                text_encoder: str, candidates: int = DEFAULT_CANDIDATES) -> Path:
    """Write MODEL_DIR/critic.safetensors atomically (float16 weights)."""
    info = {"format": FORMAT, "version": VERSION, "text_encoder": text_encoder,
            "latent_size": critic.latent_size, "text_dim": critic.text_dim,
            "max_frames": critic.max_frames, "hidden": critic.hidden, "width": critic.width,
            "candidates": candidates, "training": training}
    tensors = {k: v.detach().to(torch.float16).contiguous() for k, v in critic.state_dict().items()}
    path = Path(model_dir) / FILE
    with atomic_path(path) as tmp:  # bytes, so that the file gets atomic_path's permissions
        tmp.write_bytes(save(tensors, metadata={"mlct": json.dumps(info)}))
    return path


class Critic:
    """A loaded critic: the network, its info, and the best of N latents."""

    def __init__(self, network: LatentCritic, info: dict[str, Any]) -> None:
        self.network = network.eval().requires_grad_(False)
        self.info = info
        self.candidates = int(info.get("candidates", DEFAULT_CANDIDATES))

    @torch.inference_mode()
    def best(self, z: Tensor, frames: Tensor, text_emb: Tensor, candidates: int) -> Tensor:
        """z (B * N, n, d) autoencoder latents, N = candidates consecutive rows per prompt;
        frames (B,), text_emb (B, c) -> (B,) the index of each prompt's best row within its N."""
        rows = z.shape[0] // candidates
        scores = self.network.score(z.float(), frames.repeat_interleave(candidates).float(),
                                    text_emb.float().repeat_interleave(candidates, dim=0))
        return scores.view(rows, candidates).argmax(dim=1)


def read_critic(model_dir: str | os.PathLike, text_encoder: str, text_dim: int,
                latent_size: int) -> Critic | None:
    """The model folder's critic, None when it has none; MlctError when it is damaged or does
    not fit the model (another text encoder, latent or text width)."""
    path = Path(model_dir) / FILE
    if not path.is_file():
        return None
    try:
        with safe_open(str(path), framework="pt") as f:  # one read: metadata and tensors
            info = json.loads((f.metadata() or {})["mlct"])
            tensors = {name: f.get_tensor(name) for name in f.keys()}
        if info.get("format") != FORMAT or info.get("version") != VERSION:
            raise ValueError(f"not {FORMAT} version {VERSION}")
        network = LatentCritic(int(info["latent_size"]), int(info["text_dim"]),
                               int(info["max_frames"]), int(info["hidden"]), int(info["width"]))
        network.load_state_dict({k: v.float() for k, v in tensors.items()})
    except Exception as error:  # safetensors, json and load_state_dict raise several kinds
        raise MlctError(f"{path}: not a critic ({first_line(error)})") from None
    if info["text_encoder"] != text_encoder or info["text_dim"] != text_dim:
        raise MlctError(f"{path}: trained for the text encoder {info['text_encoder']!r}, the "
                        f"model uses {text_encoder!r}; retrain it with `mlct train critic`")
    if info["latent_size"] != latent_size:
        raise MlctError(f"{path}: made for a {info['latent_size']}-number latent, the model's "
                        f"has {latent_size}; retrain it with `mlct train critic`")
    return Critic(network, info)


def check_candidates(value: object) -> int:
    """A candidate count, or MlctError naming what is wrong."""
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_CANDIDATES:
        raise MlctError(f"candidates must be a whole number in 1..{MAX_CANDIDATES}, got {value!r}")
    return value
