"""The backend interface: a model's three networks as one backend runs them.

The core (generate/core.py) asks a backend for a batch's latents, for the features of latents,
or for both in one call; the backend owns how: plain PyTorch modules (pytorch.py), ONNX
Runtime sessions and sampler graphs (onnx/networks.py), CUDA graphs (cuda_graphs.py). What is
the model's and not the backend's (config, sampler with its time grid, normalization, latent
scale) is read here once, so that every backend samples the same way.
"""

from __future__ import annotations

import contextlib
from typing import Any, ContextManager, Sequence

import numpy as np

from mlct.config_view import model_config
from mlct.generate.samplers import Sampler, sampler_class
from mlct.motion.skeleton import get_skeleton


class Networks:
    """Text encoder, denoiser and decoder of one model on one backend.

    `decoder` has .decode(z, lengths, max_len) and .latent_shape; `denoiser` is F(x_t, t, c);
    both take and give torch tensors (the controls' guidance and large batches call them as
    the samplers do). latents/decode/features are what the core calls, one batch each."""

    name = "torch"  # the backend's name (mlct.load(..., backend=))
    # True: the core's text vectors and latents are numpy arrays (onnx, no torch), else tensors
    numpy = False
    decoder: Any
    denoiser: Any

    def __init__(self, meta: dict, device: Any = "cpu") -> None:
        self.meta = meta
        self.config = model_config(meta)  # (the bundled model's: read without pydantic)
        self.device = self.resolve_device(device)
        self.skeleton = get_skeleton(meta["skeleton"])
        # the bundle names its sampler (config.json "sampler"); it owns steps, times, guidance
        self.sampler: Sampler = sampler_class(meta["sampler"])(self.config, self.device)
        self.latent_scale = float(self.config.schedule.latent_scale)
        self._text_encoder: Any = None

    def resolve_device(self, device: Any) -> Any:
        """The torch device the networks run on (None: the CPU)."""
        from mlct.devices import resolve_device

        return resolve_device("cpu" if device is None else device)

    def critic_graph(self) -> Any:
        """The model's critic as an ONNX graph the backend runs it by (a Path), or None: the
        critic's torch network (compose/critic.py)."""
        return None

    def text_encoder(self) -> Any:
        """The frozen text encoder, loaded on first use (the bundle names it, not stores it)."""
        raise NotImplementedError

    def latents(self, cond: Any, steps: int, seed: int | Sequence[int] | None,
                guidance: float | None, uncond: Any) -> Any:
        """(B, n, d) latents for text vectors cond (B, c), `steps` network evaluations; uncond:
        the null text (1, c) when the sampler uses classifier-free guidance, else None."""
        raise NotImplementedError

    def decode(self, z: Any, lengths: Sequence[int]) -> list[np.ndarray]:
        """Latents (B, n, d) -> denormalized features, one (T_i, D) array per item."""
        raise NotImplementedError

    def features(self, cond: Any, steps: int, seed: int | Sequence[int] | None,
                 guidance: float | None, uncond: Any, lengths: Sequence[int]
                 ) -> list[np.ndarray]:
        """decode(latents(...)); a backend may do both in one call (a sampler graph)."""
        return self.decode(self.latents(cond, steps, seed, guidance, uncond), lengths)

    def running(self) -> ContextManager[None]:
        """Held around each generate() call (the onnx backend's torch threads)."""
        return contextlib.nullcontext()
