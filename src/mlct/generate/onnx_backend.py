"""The onnx backend: MotionGenerator with its networks run by ONNX Runtime on the CPU.

    gen = mlct.load("MODEL_DIR", backend="onnx")  # after `mlct convert MODEL_DIR --onnx`

Only the three networks change (onnx_bundle.py's graphs); everything around them is the torch
backend's code: prompts, lengths, seeds, the sampler objects with their time grids, clamps and
noise (drawn from the same seeded torch.Generator), latent_scale, denormalization, joints. So the
same seed gives the same motion, up to float rounding (tests/test_onnx.py: joints within 1 mm).
"""

from __future__ import annotations

import os

import numpy as np
import torch
from torch import Tensor

from mlct.devices import resolve_device
from mlct.errors import MlctError
from mlct.generate.bundle import read_bundle
from mlct.generate.onnx_bundle import DECODER_IO, DENOISER_IO, OnnxGraphs, read_onnx
from mlct.generate.pipeline import MotionGenerator
from mlct.nn.inference import weight_dtype
from mlct.nn.masks import lengths_to_mask
from mlct.onnx_io import onnxruntime_module, session
from mlct.text.base import TextEncoder


def _array(x: Tensor) -> np.ndarray:
    """A tensor as the contiguous array ONNX Runtime takes (no copy when it already is one)."""
    return np.ascontiguousarray(x.detach().numpy())


class OnnxDenoiser:
    """F(x_t, t, c) of denoiser.onnx, called as the samplers call the torch network."""

    def __init__(self, graph: os.PathLike, threads: int | None = None) -> None:
        self.session = session(graph, threads)

    def __call__(self, x_t: Tensor, t: Tensor, text_emb: Tensor) -> Tensor:
        """x_t (B, n, d), t (B,) or a scalar, text_emb (B, c) -> F (B, n, d), float32."""
        t = torch.as_tensor(t, dtype=torch.float32).reshape(-1).expand(x_t.shape[0])
        (inputs, outputs) = DENOISER_IO
        (f,) = self.session.run(list(outputs), dict(zip(inputs, map(_array, (
            x_t.float(), t, text_emb.float())))))
        return torch.from_numpy(f)


class OnnxDecoder:
    """The AE decoder of decoder.onnx, called as the pipeline calls the torch one."""

    def __init__(self, graph: os.PathLike, threads: int | None = None) -> None:
        self.session = session(graph, threads)
        shape = self.session.get_inputs()[0].shape  # ["batch", n, d]
        self.latent_shape: tuple[int, int] = (int(shape[1]), int(shape[2]))

    def decode(self, z: Tensor, lengths: Tensor, max_len: int | None = None) -> Tensor:
        """z (B, n, d), lengths (B,) -> normalized features (B, T, D), T = max_len or the
        longest; frames past an item's length are 0."""
        valid = lengths_to_mask(lengths.cpu(), max_len)  # (B, T)
        (inputs, outputs) = DECODER_IO
        (features,) = self.session.run(list(outputs), dict(zip(inputs, (
            _array(z.float()), valid.numpy()))))
        return torch.from_numpy(features)


class OnnxMotionGenerator(MotionGenerator):
    """A loaded model whose text encoder, denoiser and decoder are ONNX graphs (CPU, float32).

    threads: ONNX Runtime's intra-op threads per graph; None follows torch.get_num_threads()."""

    backend = "onnx"

    def __init__(self, meta: dict, tensors: dict[str, Tensor], graphs: OnnxGraphs,
                 device: torch.device | str | None = None, dtype: str | torch.dtype = "float32",
                 threads: int | None = None) -> None:
        if device is not None and resolve_device(device).type != "cpu":
            raise MlctError(f"the onnx backend runs on the CPU, not {device!r}; use "
                            f"backend='torch' (--backend torch) for a GPU")
        try:
            float32 = weight_dtype(dtype) == torch.float32
        except ValueError as err:
            raise MlctError(str(err)) from None
        if not float32:
            raise MlctError(f"the onnx backend runs float32 graphs; dtype {dtype!r} is the "
                            f"torch backend's (--backend torch)")
        self.graphs, self.threads = graphs, threads
        super().__init__(meta, tensors, "cpu", "float32")

    def _networks(self, tensors: dict[str, Tensor]) -> tuple[OnnxDecoder, OnnxDenoiser]:
        return (OnnxDecoder(self.graphs.decoder, self.threads),
                OnnxDenoiser(self.graphs.denoiser, self.threads))

    @property
    def text_encoder(self) -> TextEncoder:
        """text_encoder.onnx with the MiniLM tokenizer, loaded on first use."""
        if self._text_encoder is None:
            from mlct.text.minilm_onnx import OnnxMiniLMEncoder

            self._text_encoder = OnnxMiniLMEncoder(self.graphs.text_encoder,
                                                   self.meta["text_encoder"], self.threads)
        return self._text_encoder

    @classmethod
    def load(cls, path: str | os.PathLike, device: torch.device | str | None = None,
             dtype: str | torch.dtype = "float32", threads: int | None = None
             ) -> OnnxMotionGenerator:
        onnxruntime_module()  # its absence first: the fix for it comes before converting
        meta, tensors = read_bundle(path)
        return cls(meta, tensors, read_onnx(path, meta["text_encoder"]), device, dtype, threads)
