"""The text-encoder interface: what every frozen text encoder (encoders.py, minilm.py) offers."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Sequence

import numpy as np

from mlct.errors import MlctError

if TYPE_CHECKING:
    from torch import Tensor


class TextEncoder(ABC):
    """A frozen text encoder: `encode(texts)` -> (B, dim) float32 CPU tensor, no grad.

    `name` is a stable identity string (recorded in checkpoints): two encoders with the same
    name must give the same embeddings. `cache_key` names them in the on-disk embedding cache
    (text/cache.py): the name, plus a version where a rule around the network changed what
    some captions embed to, so that no cache serves a vector the rule no longer gives.
    """

    name: str
    dim: int
    _null: Tensor | None = None
    _null_array: np.ndarray | None = None

    @property
    def cache_key(self) -> str:
        return self.name

    def encode(self, texts: Sequence[str]) -> Tensor:
        """Embed a batch of captions: (B,) strings -> (B, dim) float32 on the CPU."""
        texts = _text_list(texts)
        if not texts:
            import torch

            return torch.zeros(0, self.dim)
        out = self._encode(texts)
        self._check_shape(out, texts)
        return out

    def encode_numpy(self, texts: Sequence[str]) -> np.ndarray:
        """encode's embeddings as a (B, dim) float32 numpy array; an encoder that runs without
        torch (minilm_onnx.py) computes them so, and its encode wraps this."""
        texts = _text_list(texts)
        if not texts:
            return np.zeros((0, self.dim), np.float32)
        out = self._encode_numpy(texts)
        self._check_shape(out, texts)
        return out

    def _encode_numpy(self, texts: list[str]) -> np.ndarray:
        return self._encode(texts).numpy()

    def _check_shape(self, out: object, texts: list[str]) -> None:
        """A contract check on subclasses, cheap."""
        shape = tuple(getattr(out, "shape", ()))
        if shape != (len(texts), self.dim):
            raise MlctError(f"text encoder {self.name!r} returned shape {shape}, "
                            f"expected {(len(texts), self.dim)}")

    @abstractmethod
    def _encode(self, texts: list[str]) -> Tensor:
        """(B, dim) float32 CPU embeddings of a non-empty list of strings."""

    def null_embedding(self) -> Tensor:
        """The unconditional input of classifier-free guidance: the embedding of "" (dim,)."""
        if self._null is None:
            self._null = self.encode([""])[0]
        return self._null.clone()  # a copy: callers may write into it

    def null_embedding_numpy(self) -> np.ndarray:
        """null_embedding as a numpy array (dim,)."""
        if self._null_array is None:
            self._null_array = self.encode_numpy([""])[0]
        return self._null_array.copy()

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, dim={self.dim})"


def _text_list(texts: Sequence[str]) -> list[str]:
    """Validate a batch of captions; a bare string would otherwise be encoded per character."""
    if isinstance(texts, str):
        raise MlctError("encode takes a list of texts, not a single string; wrap it in [...]")
    texts = list(texts)
    for t in texts:
        if not isinstance(t, str):
            raise MlctError(f"encode takes strings; got a {type(t).__name__}: {t!r}")
    return texts
