"""mlct: real-time text-to-motion generation with Motion Latent Consistency Training."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from mlct.generate.compose.generator import MotionGenerator


def load(path: Any = None, device: Any = None, dtype: Any = "float32",
         backend: str = "auto", threads: int | None = None) -> "MotionGenerator":
    """Load a model: `mlct.load()` the bundled one, `mlct.load(DIR)` any `mlct export` bundle;
    dtype "bfloat16" for faster, slightly rounded matrix products (docs/performance.md);
    backend "onnx" runs the networks with ONNX Runtime (`mlct convert DIR --onnx`), "torch" with
    PyTorch; "auto" (default) picks the fastest that can run the model here: onnx on the CPU in
    float32 when onnxruntime is installed, its graphs made once into the cache if need be.
    $MLCT_BACKEND overrides "auto"; the generator's backend_note says which ran and why.
    threads: the CPU threads inference uses (PyTorch's intra-op threads, process-wide, and ONNX
    Runtime's per graph); default: PyTorch's, one per core or $OMP_NUM_THREADS."""
    from mlct.generate.load import load as _load  # lazy: `import mlct` stays light

    return _load(path, device, dtype, backend, threads)
