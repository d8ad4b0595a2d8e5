"""The cuda-graphs backend: the torch pipeline replayed from CUDA graphs.

On a GPU at batch 1 the arithmetic of a sentence is microseconds; what costs is launching the
sampler's, the decoder's and the text encoder's ~1,000 small kernels one by one from Python
(docs/performance.md). Here each of them is captured once per shape bucket and replayed:
- sampling: the K consistency steps (Algorithm 2), the fresh noise of each step an input drawn
  on the host from the seeds exactly as the torch backend draws it (so the same seeds give the
  same motions), and with sample_features the decoder and the de-normalisation in the same graph;
- the text encoder (MiniLM): one graph per bucket of rows and caption length.
Buckets: the batch is padded to a power of two (padded rows repeat the first and are dropped),
the decoded length to a multiple of FRAME_STEP frames (the padded frames are masked, as in any
batch of mixed lengths). On the CPU the same code runs without graphs (tests/test_cuda_graphs.py
checks it against the torch backend there, and on a GPU when there is one).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor

from mlct.cuda_graphs import GraphCache
from mlct.diffusion.samplers import draw_noise
from mlct.generate.backends.pytorch import TorchNetworks
from mlct.generate.seeds import generators_for

FRAME_STEP = 32  # decoded lengths are padded up to a multiple of this (at most max_frames)


class QueuedNoise:
    """A noise source for the samplers (draw_noise's randn(shape) kind) that hands out the rows
    of a buffer in order: inside a graph the noise is an input, drawn on the host beforehand."""

    def __init__(self, rows: Tensor) -> None:
        self.rows, self.used = rows, 0

    def randn(self, shape: tuple[int, ...]) -> Tensor:
        if self.used >= len(self.rows) or tuple(self.rows[self.used].shape) != tuple(shape):
            raise ValueError(f"noise draw {self.used} of shape {shape} was not drawn beforehand")
        self.used += 1
        return self.rows[self.used - 1]


MAX_GRAPHS = 16  # graphs kept per generator (each holds its activations' memory pool)


class CudaGraphNetworks(TorchNetworks):
    """The torch networks whose sampling, decoding and text network replay CUDA graphs (on the
    CPU the same code runs the functions, as the tests do)."""

    name = "cuda-graphs"

    def __init__(self, meta: dict, tensors: dict[str, Tensor],
                 device: torch.device | str | None = None,
                 dtype: str | torch.dtype = "float32") -> None:
        super().__init__(meta, tensors, device, dtype)
        self._mean = self.mean.to(self.device)
        self._std = self.std.to(self.device)
        self._graphs = GraphCache(self._graph_body, MAX_GRAPHS)
        self.max_frames = self.config.data.max_motion_length

    def text_encoder(self) -> Any:
        """The frozen text encoder on the generator's device, its network graphed if it can be."""
        if self._text_encoder is None:
            from mlct.text import load_text_encoder

            encoder = load_text_encoder(self.meta["text_encoder"], device=self.device)
            if hasattr(encoder, "use_cuda_graphs"):
                encoder.use_cuda_graphs()
            self._text_encoder = encoder
        return self._text_encoder

    # -- what the graphs run: pure tensor code, no reads of the device -------------------------

    def _graph_body(self, key: tuple, *tensors: Tensor) -> Tensor:
        kind = key[0]
        if kind == "latents":  # ("latents", steps, guidance): cond, noise[, uncond]
            return self._latents(key[1], key[2], *tensors)
        if kind == "decode":  # ("decode", frames): z, lengths
            return self._features(tensors[0], tensors[1], key[1])
        if kind == "features":  # ("features", steps, guidance, frames): cond, noise, lengths[, uncond]
            cond, noise, lengths, *uncond = tensors
            return self._features(self._latents(key[1], key[2], cond, noise, *uncond), lengths,
                                  key[3])
        raise ValueError(f"unknown graph kind {kind!r}")

    def _latents(self, steps: int, guidance: float | None, cond: Tensor, noise: Tensor,
                 uncond: Tensor | None = None) -> Tensor:
        """Stage 2's latents (B, n, d) from x_T = noise[0] and the later draws noise[1:]."""
        return self.sampler.sample(self.denoiser, noise[0], cond, steps,
                                   generator=QueuedNoise(noise[1:]), guidance=guidance,
                                   uncond=uncond)

    def _features(self, z: Tensor, lengths: Tensor, frames: int) -> Tensor:
        """Denormalised features (B, frames, D), float32: pytorch.decode_with's arithmetic."""
        feats = self.decoder.decode(z / self.config.schedule.latent_scale, lengths, frames)
        return feats.float() * self._std + self._mean

    # -- the host side: buckets, noise, copies -------------------------------------------------

    @torch.inference_mode()
    def latents(self, cond: Tensor, steps: int, seed: int | Sequence[int] | None,
                guidance: float | None, uncond: Tensor | None) -> Tensor:
        batch = cond.shape[0]
        inputs = self._sampler_inputs(cond, steps, seed, uncond)
        return self._graphs(("latents", steps, guidance), *inputs,
                            read=lambda z: z[:batch].clone())

    @torch.inference_mode()
    def decode(self, z: Tensor, lengths: Sequence[int]) -> list[np.ndarray]:
        frames = self._frames(lengths)
        return self._graphs(("decode", frames), _pad_rows(z, _bucket(len(z)) - len(z)),
                            self._lengths_tensor(lengths, frames),
                            read=lambda out: _to_host(out, lengths))

    @torch.inference_mode()
    def features(self, cond: Tensor, steps: int, seed: int | Sequence[int] | None,
                 guidance: float | None, uncond: Tensor | None, lengths: Sequence[int]
                 ) -> list[np.ndarray]:
        """Sampling, decoding and de-normalisation as one graph: one replay per batch."""
        frames = self._frames(lengths)
        cond, noise, *uncond = self._sampler_inputs(cond, steps, seed, uncond)
        return self._graphs(("features", steps, guidance, frames), cond, noise,
                            self._lengths_tensor(lengths, frames), *uncond,
                            read=lambda out: _to_host(out, lengths))

    def _sampler_inputs(self, cond: Tensor, steps: int, seed: int | Sequence[int] | None,
                        uncond: Tensor | None) -> list[Tensor]:
        """cond and the noise (1 + draws, B, n, d), padded to the batch's bucket; the null
        condition last when the sampler uses classifier-free guidance."""
        batch = cond.shape[0]
        pad = _bucket(batch) - batch
        shape = (1 + self.sampler.noise_draws(steps), batch, *self.decoder.latent_shape)
        if seed is None and self.device.type == "cuda":
            # Nothing to reproduce: drawn where it is used (on the host, a big batch's noise
            # would take longer to draw than the GPU takes to sample).
            noise = torch.randn(shape, device=self.device)
        else:  # as sample_latents draws, on the host: x_T, then each step's fresh noise
            generator, host = generators_for(seed), torch.empty(0)
            noise = torch.stack([draw_noise(shape[1:], generator, host)
                                 for _ in range(shape[0])])
        inputs = [_pad_rows(cond.to(self.device), pad),
                  _pad_rows(noise.to(self.device, non_blocking=True), pad, dim=1)]
        if uncond is not None:
            inputs.append(uncond)
        return inputs

    def _frames(self, lengths: Sequence[int]) -> int:
        return min(-(-max(lengths) // FRAME_STEP) * FRAME_STEP, self.max_frames)

    def _lengths_tensor(self, lengths: Sequence[int], frames: int) -> Tensor:
        padded = list(lengths) + [frames] * (_bucket(len(lengths)) - len(lengths))
        return torch.tensor(padded, dtype=torch.long).to(self.device, non_blocking=True)


def _bucket(batch: int) -> int:
    """The batch size a graph is captured for: the next power of two."""
    return 1 << (batch - 1).bit_length()


def _pad_rows(x: Tensor, pad: int, dim: int = 0) -> Tensor:
    """x with `pad` more rows along dim, copies of the first (dropped after the graph)."""
    if not pad:
        return x
    first = x.narrow(dim, 0, 1)
    return torch.cat([x, first.expand(*(pad if d == dim else -1 for d in range(x.dim())))], dim)


def _to_host(out: Tensor, lengths: Sequence[int]) -> list[np.ndarray]:
    """One (T_i, D) array per item from the graph's output buffer: one copy to the host (into
    pinned memory on a GPU, so the copy runs at the bus's speed), then views."""
    out = out[: len(lengths)]
    host = out  # on the CPU the function's own fresh output: no graph buffer to copy out of
    if out.device.type == "cuda":
        host = torch.empty(out.shape, dtype=out.dtype, pin_memory=True)
        host.copy_(out, non_blocking=True)
        torch.cuda.current_stream(out.device).synchronize()
    array = host.numpy()  # numpy's slicing: a torch view per item costs ~10x more
    return [array[i, :n] for i, n in enumerate(lengths)]


def check_cuda_device(device: torch.device | str | None) -> None:
    """A one-line MlctError unless `device` is a usable CUDA device (the backend's only one)."""
    from mlct.devices import resolve_device
    from mlct.errors import MlctError

    if device is None or resolve_device(device).type != "cuda":
        raise MlctError(f"the cuda-graphs backend needs a CUDA device, not {device or 'cpu'}"
                        "; use --device cuda, or the torch or onnx backend")
