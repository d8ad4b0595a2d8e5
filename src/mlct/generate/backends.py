"""The inference backends and `load`, which picks one by name: a new backend is a loader here.

- torch: the networks in PyTorch (mlct.nn.inference's layers), on the CPU or a GPU, float32 or
  bfloat16 products (pipeline.py);
- onnx: the same pipeline with the three networks as ONNX graphs run by ONNX Runtime on the CPU
  (onnx_backend.py; the graphs come from `mlct convert MODEL_DIR --onnx`).
"""

from __future__ import annotations

import os
from typing import Callable

import torch

from mlct.errors import MlctError
from mlct.generate.onnx_backend import OnnxMotionGenerator
from mlct.generate.pipeline import MotionGenerator, bundled_model_dir

BACKENDS: dict[str, Callable[..., MotionGenerator]] = {
    "torch": MotionGenerator.load,
    "onnx": OnnxMotionGenerator.load,
}


def load(path: str | os.PathLike | None = None, device: torch.device | str | None = None,
         dtype: str | torch.dtype = "float32", backend: str = "torch") -> MotionGenerator:
    """Load an inference bundle written by `mlct export`; with no path, the bundled model.
    dtype: "float32" or "bfloat16" matrix products (the torch backend); backend: a BACKENDS
    name."""
    if path is not None and not isinstance(path, (str, os.PathLike)):
        raise MlctError(f"path must be a model directory (str or Path), not {type(path).__name__}")
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise MlctError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    return BACKENDS[backend](bundled_model_dir() if path is None else path, device, dtype)
