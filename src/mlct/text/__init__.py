"""Text encoders (bundled MiniLM; CLIP or sentence-transformers from a local dir), their cache."""

from mlct.text.cache import CachedTextEncoder, EmbeddingCache, default_cache_dir
from mlct.text.encoders import (
    MINILM,
    ClipTextEncoder,
    SentenceTransformerEncoder,
    TextEncoder,
    bundled_minilm_path,
    load_text_encoder,
)
from mlct.text.minilm import MiniLMEncoder

__all__ = [
    "MINILM",
    "CachedTextEncoder",
    "ClipTextEncoder",
    "EmbeddingCache",
    "MiniLMEncoder",
    "SentenceTransformerEncoder",
    "TextEncoder",
    "bundled_minilm_path",
    "default_cache_dir",
    "load_text_encoder",
]
