"""Word vectors learned with the evaluator, for datasets without the evaluator's GloVe files.

The reference evaluator (EricGuo5513/text-to-motion) reads fixed GloVe vectors (`our_vab_*`).
Without them, `train_evaluator` learns a 300-d vector per word of the training captions jointly
with the text encoder. This class then plays the WordVectorizer's part with the learned table:
the same `word/POS` tokens, the same POS one-hots (VIP classes, OTHER for unknown words), and
an unknown word gets the `unk` vector.

File format (`learned_words.npz`, numpy, no pickle): `words` (N,) str, `vectors` (N, dim)
float32, `format` = "mlct-learned-words". Rows 0..2 are `unk`, `sos`, `eos`.
"""

from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.eval.judge.word_vectors import (
    POS_ENUMERATOR,
    UNKNOWN_WORD,
    VIP_WORDS,
    WORD_DIM,
    WordVectorizer,
)
from mlct.io import write_bytes

SPECIAL_WORDS = (UNKNOWN_WORD, "sos", "eos")  # framing tokens sos/OTHER, eos/OTHER; pad unk/OTHER
FORMAT = "mlct-learned-words"


def token_word(token: str) -> str:
    """The word of a `word/POS` token."""
    word, sep, _ = token.rpartition("/")
    if not sep or not word:
        raise MlctError(f"token {token!r} is not of the form word/POS")
    return word


def build_vocabulary(token_lists: Iterable[Sequence[str]]) -> list[str]:
    """`unk`, `sos`, `eos`, then the other words of the tokens, sorted (a stable order)."""
    words = {token_word(token) for tokens in token_lists for token in tokens}
    return list(SPECIAL_WORDS) + sorted(words - set(SPECIAL_WORDS))


class LearnedWordVectors(WordVectorizer):
    """token `word/POS` -> (learned word vector (dim,), POS one-hot (15,)), as WordVectorizer."""

    # The parent's __init__ reads GloVe files; this one takes the table. Lookup (__getitem__,
    # encode, pos_onehot) is the parent's, so both vectorizers follow the same token rules.
    def __init__(self, words: Sequence[str], vectors: np.ndarray) -> None:
        words = list(words)
        vectors = np.asarray(vectors, dtype=np.float32)
        if vectors.ndim != 2 or len(vectors) != len(words):
            raise MlctError(f"learned word vectors: {len(words)} words but vectors of shape "
                            f"{vectors.shape}")
        if len(set(words)) != len(words):
            raise MlctError("learned word vectors: a word appears twice")
        missing = [w for w in SPECIAL_WORDS if w not in words]
        if missing:
            raise MlctError(f"learned word vectors: no {', '.join(map(repr, missing))} word")
        if not np.isfinite(vectors).all():
            raise MlctError("learned word vectors are not finite everywhere")
        self.words = words
        self.vectors = vectors
        self.word2idx = {word: row for row, word in enumerate(words)}
        self.word2vec = {word: vectors[row] for row, word in enumerate(words)}
        self._vip_class = {word: cls for cls, vip in reversed(VIP_WORDS.items()) for word in vip}

    @property
    def dim(self) -> int:
        return int(self.vectors.shape[1])

    @classmethod
    def initial(cls, words: Sequence[str], dim: int = WORD_DIM,
                rng: np.random.Generator | None = None) -> LearnedWordVectors:
        """A table of N(0, 1) vectors (nn.Embedding's initialization), to be trained."""
        rng = np.random.default_rng(0) if rng is None else rng
        return cls(words, rng.standard_normal((len(words), dim)).astype(np.float32))

    def ids(self, tokens: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """Tokens -> table rows (L,) int64 and POS one-hots (L, 15): what `encode` looks up."""
        if not tokens:
            return np.zeros(0, np.int64), np.zeros((0, len(POS_ENUMERATOR)), np.float32)
        rows = [self.word2idx.get(token_word(token), self.word2idx[UNKNOWN_WORD])
                for token in tokens]
        return np.asarray(rows, dtype=np.int64), np.stack([self[token][1] for token in tokens])

    def save(self, path: str | os.PathLike) -> None:
        """Write `words`, `vectors`, `format` as one .npz (atomically)."""
        buffer = io.BytesIO()
        np.savez(buffer, words=np.asarray(self.words, dtype=str), vectors=self.vectors,
                 format=np.asarray(FORMAT))
        write_bytes(path, buffer.getvalue())

    @classmethod
    def load(cls, path: str | os.PathLike) -> LearnedWordVectors:
        path = Path(path)
        if not path.is_file():
            raise MlctError(f"{path}: missing (the evaluator's learned word vectors)")
        try:
            data = np.load(path, allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):
                raise ValueError("a single array, not an .npz archive")
            with data:
                arrays = {key: data[key] for key in data.files}
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
            raise MlctError(f"{path}: not an mlct learned-words file ({error})") from None
        if str(arrays.get("format", "")) != FORMAT or not {"words", "vectors"} <= set(arrays):
            raise MlctError(f"{path}: not an mlct learned-words file (needs words, vectors, "
                            f"format={FORMAT!r})")
        words, vectors = arrays["words"], arrays["vectors"]
        if words.ndim != 1 or words.dtype.kind != "U":
            raise MlctError(f"{path}: words must be a 1-d string array")
        return cls([str(w) for w in words], vectors)
