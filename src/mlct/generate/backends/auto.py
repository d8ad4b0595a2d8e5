"""backend="auto" (the default of mlct.load, `mlct generate` and `mlct serve`): the fastest
backend that can run the model here and gives the model's own motions, and one line saying
which and why (`--verbose`).

The onnx backend when ONNX Runtime is installed, the model runs on the CPU in float32 and its
text encoder has an ONNX graph: at batch 1 it is 1.3-2x faster than eager PyTorch on the
bundled model (docs/performance.md) and gives the same motions for the same seeds (within
0.01 mm; tests/test_onnx.py). Not onnx-int8 (the denoiser's products in int8 with a scale per
32 weights, ~1.4x faster again): its motions are as good by the read-outs but not the same
motions (on the benchmark's test captions the joints move 7.5 mm on average, 12% of the
motions by more than 1 cm: docs/performance.md), so it is asked for by name,
or by graphs `mlct convert --onnx --int8` put
in the model directory. On a CUDA device the cuda-graphs backend. Otherwise the torch backend
(a GPU, bfloat16, another text encoder, no onnxruntime). MLCT_BACKEND=torch|onnx|...
overrides the choice.

Where the graphs come from: MODEL_DIR/onnx/ when `mlct convert` put them there (used as they
are: float32, or int8 after `--int8`); else the cache, default_cache_dir()/onnx/KEY (KEY: a
digest of the weights, the config, the graph format and int8), made on first use when the onnx
package (which writes graphs) is installed. Making
them takes a few seconds once; it goes into a fresh directory beside the entry that is renamed
into place, so a reader never sees half a conversion and two processes converting at once
both succeed (the second one's copy is dropped).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from mlct.errors import MlctError
from mlct.generate.bundle import CONFIG, read_config

ENV = "MLCT_BACKEND"


def choose_backend(path: Path, device: Any, dtype: Any) -> tuple[str, Path | None, str]:
    """(backend, the directory of its ONNX graphs or None, why) for model directory `path`."""
    if device is not None and not (isinstance(device, str) and device.strip().lower() == "cpu"):
        from mlct.devices import resolve_device

        kind = resolve_device(device).type
    else:
        kind = "cpu"  # (None: the CPU for auto too; said without torch)
    if kind == "cuda":
        return "cuda-graphs", None, (f"the model runs on {device}, where launching kernels one "
                                     "by one costs more than their arithmetic")
    if kind != "cpu":
        return "torch", None, f"the model runs on {device}"
    if dtype != "float32" and not _is_torch_float32(dtype):
        return "torch", None, f"dtype {dtype} is the torch backend's"
    try:
        import onnxruntime
    except ImportError:
        return "torch", None, "onnxruntime is not installed (pip install onnxruntime==1.32.0)"
    from mlct.generate.backends.onnx.bundle import MANIFEST, ONNX_DIR, read_onnx
    from mlct.text.minilm_onnx import ONNX_SPECS

    if not (path / CONFIG).is_file():  # not a model: loading it says so, in its words
        return "torch", None, "no model config"
    # config.json only: the weights are read once, by the backend that loads them
    meta = read_config(path)
    if str(meta.get("text_encoder", "")).strip().lower() not in ONNX_SPECS:
        return "torch", None, f"the text encoder {meta['text_encoder']!r} has no ONNX graph"
    runtime = f"ONNX Runtime {onnxruntime.__version__}"
    if (path / ONNX_DIR / MANIFEST).is_file():
        try:  # graphs `mlct convert` put there, made from these weights: as they are
            graphs = read_onnx(path, meta["text_encoder"])
            if graphs.manifest.get("int8"):
                return "onnx-int8", path / ONNX_DIR, (f"{runtime}, graphs in {path / ONNX_DIR}"
                                                      f", the denoiser's products in int8")
            return "onnx", path / ONNX_DIR, f"{runtime}, graphs in {path / ONNX_DIR}"
        except MlctError:
            pass  # stale graphs there: the cache's, made from these weights, are used instead
    try:
        cached = find_graphs(path, meta["text_encoder"], int8=False)
    except MlctError as err:
        return "torch", None, str(err)
    return "onnx", cached, f"{runtime}, graphs in {cached}"


def find_graphs(path: Path, text_encoder: str, int8: bool) -> Path:
    """The folder of the model's ONNX graphs of this kind (float32, or the denoiser's products in
    int8): MODEL_DIR/onnx when `mlct convert` put such graphs there, else the cache's entry,
    converted on first use. MlctError saying why when there are none and none can be made."""
    from mlct.generate.backends.onnx.bundle import MANIFEST, ONNX_DIR, read_onnx

    if (path / ONNX_DIR / MANIFEST).is_file():
        try:
            if bool(read_onnx(path, text_encoder).manifest.get("int8")) == int8:
                return path / ONNX_DIR
        except MlctError:
            pass  # stale: the cache's
    from mlct.errors import require_torch

    require_torch("a model without ONNX graphs of its own (made once into the cache)")
    cached = default_graph_dir(path, int8)
    if (cached / MANIFEST).is_file():
        try:
            read_onnx(path, text_encoder, cached)
        except MlctError:  # damaged: made again
            shutil.rmtree(cached, ignore_errors=True)
    if not (cached / MANIFEST).is_file():
        try:
            convert_into_cache(path, cached, int8)
        except MlctError as err:
            raise MlctError(f"converting to ONNX failed ({err})") from None
    return cached


def default_graph_dir(path: Path, int8: bool = False) -> Path:
    """The cache entry of the ONNX graphs of the model in `path` (int8: with the denoiser's
    products in int8)."""
    from mlct.generate.backends.onnx.bundle import ONNX_VERSION, weights_digest
    from mlct.text import default_cache_dir

    key = hashlib.sha256()
    key.update(weights_digest(path).encode())
    key.update((path / CONFIG).read_bytes())
    import torch  # the cache's graphs are made, and keyed, by torch

    key.update(f"mlct-onnx {ONNX_VERSION} torch {torch.__version__}".encode())
    key.update(b" text encoder with fused attention")  # not the older, unfused graphs
    if int8:
        key.update(b" int8 denoiser, blockwise, small products float32")  # not older graphs
    return default_cache_dir() / "onnx" / key.hexdigest()[:24]


def convert_into_cache(path: Path, entry: Path, int8: bool = False) -> Path:
    """Write the model's graphs into the cache entry `entry` (see the module docstring)."""
    from mlct.generate.backends.onnx.convert import write_onnx_graphs

    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{entry.name}.partial-", dir=entry.parent))
    except OSError as err:
        raise MlctError(f"cannot write the ONNX cache {entry.parent}: {err}") from None
    try:
        write_onnx_graphs(path, work, int8)
        work.chmod(0o755)
        try:
            os.rename(work, entry)  # fails when another process got there first: theirs stays
        except OSError:
            if not entry.is_dir():
                raise
    except OSError as err:
        raise MlctError(f"cannot write the ONNX cache {entry}: {err}") from None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return entry


def _is_torch_float32(dtype: Any) -> bool:
    """Is dtype torch.float32 (asked without importing torch: only torch makes one)?"""
    import sys

    torch = sys.modules.get("torch")
    return torch is not None and dtype is torch.float32

