"""The files the package ships beside its code, by name: the bundled model, its ONNX graphs
(written by `python -m mlct.onnx_assets`), the all-MiniLM-L6-v2 text encoder they read."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

ASSETS = Path(__file__).resolve().parent / "assets"
MODEL_DIR = ASSETS / "model"  # the bundled model (generate's bundled_model_dir)
SHIPPED_DIR = MODEL_DIR / "onnx"  # its graphs, where the loader looks for a model's own
MINILM_DIR = ASSETS / "minilm"  # sentence-transformers/all-MiniLM-L6-v2 (Apache-2.0)
MINILM_WEIGHTS = "model.safetensors"
# what the graphs' manifest (onnx.json) records beside backends/onnx/bundle.py's fields: the
# digests of the MiniLM's and the critic's weights, and the critic's graph
TEXT_ENCODER_WEIGHTS = "minilm_sha256"
CRITIC, CRITIC_WEIGHTS = "critic.onnx", "critic_sha256"


def is_shipped_model(model_dir: str | os.PathLike | None) -> bool:
    """Is this folder the bundled model, whose files the tests check (its config validated,
    the digests its graphs record: tests/test_config_view.py, test_onnx_assets.py)?"""
    return model_dir is not None and Path(model_dir).resolve() == MODEL_DIR


def file_digest(path: Path) -> str:
    """The sha256 of a file (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
