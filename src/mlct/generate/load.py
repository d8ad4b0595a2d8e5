"""`load`: a model's generator on the backend asked for by name; a new backend is a loader here.

A generator is the composer (compose/generator.py) over the core (core.py), which holds the
model's networks as one backend runs them (backends/):
- torch: the networks in PyTorch (mlct.nn.inference's layers), on the CPU or a GPU, float32 or
  bfloat16 products (backends/pytorch.py);
- cuda-graphs: the torch networks on a GPU, replayed from CUDA graphs (backends/cuda_graphs.py);
- onnx: the three networks as ONNX graphs run by ONNX Runtime on the CPU
  (backends/onnx/networks.py; the graphs `mlct convert MODEL_DIR --onnx` put in the model
  directory, else made once into the cache, as auto does); a batch of TORCH_MIN_BATCH latents
  or more is handed to the torch networks, faster there;
- onnx-int8: the same with the denoiser's matrix products in int8 (the graphs from `mlct
  convert MODEL_DIR --onnx --int8` or made once into the cache): ~2x faster sampling, motions
  as good by the read-outs but not the float32 ones (asked for by name: docs/performance.md);
- auto (the default): the fastest of them that can run the model here and gives its own
  motions (float32; backends/auto.py).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from mlct.errors import MlctError, require_torch
from mlct.generate.backends.auto import ENV, choose_backend, find_graphs
from mlct.generate.backends.onnx.networks import OnnxNetworks, check_device_and_dtype
from mlct.generate.bundle import bundled_model_dir, read_bundle
from mlct.generate.compose.actions import plain_subject
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.core import MotionCore

if TYPE_CHECKING:  # the onnx path imports no torch: the torch backends load it when asked for
    import torch


def torch_generator(meta: dict, tensors: dict[str, torch.Tensor],
                    device: torch.device | str | None = None,
                    dtype: str | torch.dtype = "float32") -> MotionGenerator:
    """A bundle's (bundle.read_bundle) generator on the torch backend."""
    from mlct.generate.backends.pytorch import TorchNetworks

    return MotionGenerator(MotionCore(TorchNetworks(meta, tensors, device, dtype), plain_subject))


def cuda_graph_generator(meta: dict, tensors: dict[str, torch.Tensor],
                         device: torch.device | str | None = None,
                         dtype: str | torch.dtype = "float32") -> MotionGenerator:
    """A bundle's generator on the cuda-graphs backend (on the CPU it runs the same code
    without graphs, as the tests do there)."""
    from mlct.generate.backends.cuda_graphs import CudaGraphNetworks

    return MotionGenerator(MotionCore(CudaGraphNetworks(meta, tensors, device, dtype), plain_subject))


def onnx_generator(meta: dict, tensors: dict[str, Any], graphs: Any,
                   threads: int | None = None) -> MotionGenerator:
    """A bundle's generator on the onnx backend, on these graphs (onnx/bundle.read_onnx)."""
    return MotionGenerator(MotionCore(OnnxNetworks(meta, tensors, graphs, threads), plain_subject))


def load_torch(path: str | os.PathLike, device: torch.device | str | None = None,
               dtype: str | torch.dtype = "float32") -> MotionGenerator:
    require_torch("the torch backend")
    return torch_generator(*read_bundle(path), device, dtype)


def load_cuda_graphs(path: str | os.PathLike, device: torch.device | str | None = None,
                     dtype: str | torch.dtype = "float32") -> MotionGenerator:
    """The cuda-graphs backend of mlct.load: a CUDA device only."""
    require_torch("the cuda-graphs backend")
    from mlct.generate.backends.cuda_graphs import check_cuda_device

    check_cuda_device(device)
    return cuda_graph_generator(*read_bundle(path), device, dtype)


def load_onnx(path: str | os.PathLike, device: torch.device | str | None = None,
              dtype: str | torch.dtype = "float32", threads: int | None = None,
              graphs: str | os.PathLike | None = None) -> MotionGenerator:
    """The onnx backend on the graphs in `graphs` (default: path/onnx)."""
    from mlct.generate.backends.onnx.bundle import read_onnx
    from mlct.onnx_io import onnxruntime_module

    onnxruntime_module()  # its absence first: the fix for it comes before converting
    check_device_and_dtype(device, dtype)
    meta, tensors = read_bundle(path, numpy=True)
    return onnx_generator(meta, tensors, read_onnx(path, meta["text_encoder"], graphs), threads)


def _onnx(path: Path, device: torch.device | str | None = None,
          dtype: str | torch.dtype = "float32", threads: int | None = None) -> MotionGenerator:
    """The onnx backend on the graphs `mlct convert --onnx [--int8]` put in the model folder, as
    they are (checked: graphs of other weights are refused, saying how to make them again);
    without any there (the bundled model, which cannot hold graphs of its own), on the cache's
    float32 graphs, made once as auto makes them."""
    from mlct.generate.backends.onnx.bundle import MANIFEST, ONNX_DIR

    if (path / ONNX_DIR / MANIFEST).is_file():
        return load_onnx(path, device, dtype, threads)
    return _cached(path, device, dtype, int8=False, threads=threads)


def _onnx_int8(path: Path, device: torch.device | str | None = None,
               dtype: str | torch.dtype = "float32", threads: int | None = None
               ) -> MotionGenerator:
    """The onnx backend on graphs whose denoiser products are int8: the model folder's when
    `mlct convert --onnx --int8` made them, else the cache's (made once)."""
    return _cached(path, device, dtype, int8=True, threads=threads)


def _cached(path: Path, device: torch.device | str | None, dtype: str | torch.dtype,
            int8: bool, threads: int | None = None) -> MotionGenerator:
    """The onnx backend on auto_backend.find_graphs' graphs of this kind."""
    from mlct.onnx_io import onnxruntime_module

    onnxruntime_module()  # its absence first: the fix for it comes before converting
    check_device_and_dtype(device, dtype)  # and a device or dtype it cannot run
    return load_onnx(path, device, dtype, threads,
                     graphs=find_graphs(path, _config(path)["text_encoder"], int8))


def _config(path: Path) -> dict:
    """The model's config.json alone (the weights are read once, by the backend that loads
    them); one line saying what is wrong when `path` is not a model."""
    from mlct.generate.bundle import CONFIG, read_bundle, read_config

    if not (path / CONFIG).is_file():
        read_bundle(path)  # not a model: one line saying what is wrong, before converting
    return read_config(path)


BACKENDS: dict[str, Callable[..., MotionGenerator]] = {
    "torch": load_torch,
    "onnx": _onnx,
    "onnx-int8": _onnx_int8,
    "cuda-graphs": load_cuda_graphs,
}


def check_threads(threads: object) -> int | None:
    """None, or a thread count of at least 1; a one-line MlctError otherwise."""
    if threads is None:
        return None
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise MlctError(f"threads must be a whole number of at least 1, got {threads!r}")
    return threads


def check_options(device: torch.device | str | None, dtype: str | torch.dtype,
                  backend: str = "auto") -> tuple[str, str]:
    """The backend mlct.load would run ($MLCT_BACKEND for "auto") and where that name came
    from, or a one-line MlctError for a device, dtype or backend, or a combination of them,
    that no model could run: all said before a model is read (mlct generate calls it first)."""
    if backend == "auto" and os.environ.get(ENV):
        backend, origin = os.environ[ENV].strip().lower(), f"${ENV}"
    else:
        origin = "asked for"
    if not isinstance(backend, str) or backend not in (*BACKENDS, "auto"):
        where = f" in ${ENV}" if origin != "asked for" else ""
        raise MlctError(f"unknown backend {backend!r}{where}; choose one of auto, "
                        f"{', '.join(BACKENDS)}")
    if backend in ("onnx", "onnx-int8", "auto") and _cpu_float32(device, dtype):
        return backend, origin  # the CPU in float32: nothing torch would have to say
    require_torch(f"device {device!r}, dtype {dtype!r}" if backend in ("onnx", "onnx-int8",
                                                                       "auto")
                  else f"the {backend} backend")
    from mlct.devices import resolve_device
    from mlct.nn.inference import weight_dtype

    if device is not None:
        resolve_device(device)
    try:
        weight_dtype(dtype)
    except ValueError as err:
        raise MlctError(str(err)) from None
    if backend in ("onnx", "onnx-int8"):
        check_device_and_dtype(device, dtype)
    if backend == "cuda-graphs":
        from mlct.generate.backends.cuda_graphs import check_cuda_device

        check_cuda_device(device)
    return backend, origin


def _cpu_float32(device: Any, dtype: Any) -> bool:
    """The CPU (None or "cpu") in float32 ("float32"), told without torch."""
    cpu = device is None or (isinstance(device, str) and device.strip().lower() == "cpu")
    return cpu and isinstance(dtype, str) and dtype == "float32"


def load(path: str | os.PathLike | None = None, device: torch.device | str | None = None,
         dtype: str | torch.dtype = "float32", backend: str = "auto",
         threads: int | None = None) -> MotionGenerator:
    """Load an inference bundle written by `mlct export`; with no path, the bundled model.
    dtype: "float32" or "bfloat16" matrix products (the torch backend); backend: a BACKENDS
    name, or "auto" (the default): the fastest one that can run the model here
    (backends/auto.py; $MLCT_BACKEND overrides it). The generator's `backend_note` says which
    backend runs it and why. threads: PyTorch's intra-op threads (process-wide: the torch
    backends and the torch work around the graphs) and ONNX Runtime's per graph; None keeps
    PyTorch's (one per core, or $OMP_NUM_THREADS)."""
    if path is not None and not isinstance(path, (str, os.PathLike)):
        raise MlctError(f"path must be a model directory (str or Path), not {type(path).__name__}")
    backend, origin = check_options(device, dtype, backend)
    if check_threads(threads) is not None and (backend in ("torch", "cuda-graphs")
                                               or "torch" in sys.modules):
        import torch  # every torch backend takes torch's count, the onnx ones each graph's

        torch.set_num_threads(threads)
    folder = bundled_model_dir() if path is None else Path(path)
    if backend not in ("onnx", "onnx-int8") and not _cpu_float32(device, dtype):
        from mlct.cpu_features import kernel_dtype  # (the onnx ones refuse bfloat16 by name)

        dtype = kernel_dtype(dtype, device)  # float32, said, where the CPU has no bf16 kernels
    if backend in ("onnx", "onnx-int8"):
        generator = BACKENDS[backend](folder, device, dtype, threads=threads)
        generator.backend = backend
        generator.backend_note = f"{backend} ({origin})"
        return generator
    if backend != "auto":
        generator = BACKENDS[backend](folder, device, dtype)
        generator.backend = backend
        generator.backend_note = f"{backend} ({origin})"
        return generator
    chosen, graphs, why = choose_backend(folder, device, dtype)
    if chosen in ("onnx", "onnx-int8"):
        try:
            generator = load_onnx(folder, device, dtype, threads, graphs=graphs)
            generator.backend = chosen
        except MlctError as err:  # e.g. a graph ONNX Runtime cannot load: torch still can
            chosen, why = "torch", f"the {chosen} backend failed to load ({err})"
    if chosen in ("cuda-graphs", "torch") and threads is not None:
        import torch

        torch.set_num_threads(threads)
    if chosen == "cuda-graphs":
        generator = load_cuda_graphs(folder, device, dtype)
    if chosen == "torch":
        generator = load_torch(folder, device, dtype)
    generator.backend_note = f"{chosen} (auto: {why})"
    return generator
