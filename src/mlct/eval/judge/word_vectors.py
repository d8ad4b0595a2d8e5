"""GloVe word vectors and part-of-speech one-hots for the evaluator's text encoder.

Facts from EricGuo5513/text-to-motion utils/word_vectorizer.py: the vocabulary is three files,
`{prefix}_data.npy` (N, 300) vectors, `{prefix}_words.pkl` (the words, a list) and
`{prefix}_idx.pkl` (dict word -> row), prefix `our_vab`; tokens are `word/POS` (spaCy coarse
tags); the 15 POS classes below; words of the five VIP lists take their VIP class instead of
their tag; a tag outside the classes is OTHER; an unknown word gets the `unk` vector and OTHER.
"""

from __future__ import annotations

import io
import os
import pickle
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from mlct.errors import MlctError

WORD_DIM = 300

POS_ENUMERATOR: dict[str, int] = {
    "VERB": 0, "NOUN": 1, "DET": 2, "ADP": 3, "NUM": 4, "AUX": 5, "PRON": 6, "ADJ": 7,
    "ADV": 8, "Loc_VIP": 9, "Body_VIP": 10, "Obj_VIP": 11, "Act_VIP": 12, "Desc_VIP": 13,
    "OTHER": 14,
}

# Checked in this order; the first list holding the word gives its class (as the reference).
VIP_WORDS: dict[str, tuple[str, ...]] = {
    "Loc_VIP": ("left", "right", "clockwise", "counterclockwise", "anticlockwise", "forward",
                "back", "backward", "up", "down", "straight", "curve"),
    "Body_VIP": ("arm", "chin", "foot", "feet", "face", "hand", "mouth", "leg", "waist", "eye",
                 "knee", "shoulder", "thigh"),
    "Obj_VIP": ("stair", "dumbbell", "chair", "window", "floor", "car", "ball", "handrail",
                "baseball", "basketball"),
    "Act_VIP": ("walk", "run", "swing", "pick", "bring", "kick", "put", "squat", "throw", "hop",
                "dance", "jump", "turn", "stumble", "stop", "sit", "lift", "lower", "raise",
                "wash", "stand", "kneel", "stroll", "rub", "bend", "balance", "flap", "jog",
                "shuffle", "lean", "rotate", "spin", "spread", "climb"),
    "Desc_VIP": ("slowly", "carefully", "fast", "careful", "slow", "quickly", "happy", "angry",
                 "sad", "happily", "angrily", "sadly"),
}

UNKNOWN_WORD = "unk"


class _PlainDataUnpickler(pickle.Unpickler):
    """Unpickles plain containers only: any class or function reference is refused.

    Trust boundary: the vocabulary pickles come from a download, and unpickling can run code.
    A list of str and a dict of str -> int need no global at all, so refusing every global keeps
    the official files loadable while closing that door.
    """

    def find_class(self, module: str, name: str) -> Any:
        raise pickle.UnpicklingError(f"refusing to load {module}.{name}")


def _load_pickle(path: Path) -> Any:
    try:
        return _PlainDataUnpickler(io.BytesIO(path.read_bytes())).load()
    except (pickle.UnpicklingError, EOFError, ValueError) as error:
        raise MlctError(f"{path}: not a plain pickled list/dict ({error})") from None


class WordVectorizer:
    """token `word/POS` -> (word vector (300,), POS one-hot (15,)), both float32."""

    def __init__(self, directory: str | os.PathLike, prefix: str = "our_vab") -> None:
        root = Path(directory)
        paths = {kind: root / f"{prefix}_{kind}" for kind in ("data.npy", "words.pkl", "idx.pkl")}
        for path in paths.values():
            if not path.is_file():
                raise MlctError(f"{path}: missing; give the directory holding the evaluator's "
                                f"GloVe files {prefix}_data.npy, {prefix}_words.pkl, "
                                f"{prefix}_idx.pkl (text-to-motion's glove/)")
        try:
            vectors = np.load(paths["data.npy"], allow_pickle=False)
        except (ValueError, OSError, EOFError) as error:
            raise MlctError(f"{paths['data.npy']}: cannot read ({error})") from None
        words = _load_pickle(paths["words.pkl"])
        word2idx = _load_pickle(paths["idx.pkl"])
        if vectors.ndim != 2 or vectors.shape[1] != WORD_DIM:
            raise MlctError(f"{paths['data.npy']}: shape {vectors.shape}, expected (N, {WORD_DIM})")
        if not isinstance(word2idx, dict):
            raise MlctError(f"{paths['idx.pkl']}: expected a dict word -> row, "
                            f"got {type(word2idx).__name__}")
        vectors = vectors.astype(np.float32, copy=False)
        self.word2vec: dict[str, np.ndarray] = {}
        for word in words:
            row = word2idx.get(word)
            if not isinstance(word, str) or not isinstance(row, int) or not 0 <= row < len(vectors):
                raise MlctError(f"{paths['idx.pkl']}: word {word!r} has no valid row "
                                f"(got {row!r}, {len(vectors)} vectors)")
            self.word2vec[word] = vectors[row]
        if UNKNOWN_WORD not in self.word2vec:
            raise MlctError(f"{paths['words.pkl']}: no {UNKNOWN_WORD!r} word "
                            f"(unknown words use its vector)")
        self._vip_class = {word: cls for cls, vip in reversed(VIP_WORDS.items()) for word in vip}

    def __len__(self) -> int:
        return len(self.word2vec)

    @staticmethod
    def pos_onehot(pos: str) -> np.ndarray:
        """(15,) one-hot of a POS class; a tag outside POS_ENUMERATOR counts as OTHER."""
        onehot = np.zeros(len(POS_ENUMERATOR), dtype=np.float32)
        onehot[POS_ENUMERATOR.get(pos, POS_ENUMERATOR["OTHER"])] = 1.0
        return onehot

    def __getitem__(self, token: str) -> tuple[np.ndarray, np.ndarray]:
        word, sep, pos = token.rpartition("/")
        if not sep:
            raise MlctError(f"token {token!r} is not of the form word/POS")
        vector = self.word2vec.get(word)
        if vector is None:  # unknown words lose their tag too
            return self.word2vec[UNKNOWN_WORD], self.pos_onehot("OTHER")
        return vector, self.pos_onehot(self._vip_class.get(word, pos))

    def encode(self, tokens: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """Tokens of one sentence -> word vectors (L, 300) and POS one-hots (L, 15)."""
        pairs = [self[token] for token in tokens]
        if not pairs:
            return (np.zeros((0, WORD_DIM), np.float32),
                    np.zeros((0, len(POS_ENUMERATOR)), np.float32))
        return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])
