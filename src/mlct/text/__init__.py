"""Text encoders (bundled MiniLM; CLIP or sentence-transformers from a local dir), their cache.

The names below load their module on first use (PEP 562), so that the ONNX text encoder
(text/minilm_onnx.py) is imported without the torch ones."""

from __future__ import annotations

import importlib
from typing import Any

_HOMES = {
    "CachedTextEncoder": "cache",
    "EmbeddingCache": "cache",
    "default_cache_dir": "cache",
    "MINILM": "minilm_files",
    "bundled_minilm_path": "minilm_files",
    "ClipTextEncoder": "encoders",
    "SentenceTransformerEncoder": "encoders",
    "load_text_encoder": "encoders",
    "TextEncoder": "base",
    "MiniLMEncoder": "minilm",
}

__all__ = sorted(_HOMES)


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module 'mlct.text' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"mlct.text.{_HOMES[name]}"), name)
    globals()[name] = value
    return value
