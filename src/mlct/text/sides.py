"""Side contrast: make "left" and "right" far apart in a pooled sentence embedding.

A pooled MiniLM vector barely tells the sides apart: "a person waves with the left hand" and
"... the right hand" are 0.19 apart (cosine 0.98) while "waves" and "claps" are 1.07 apart, so
a denoiser conditioned on it confuses the sides (docs/training.md, "Sides"). Ours, not the
paper's: the embedding of a caption that names a side is pushed away from the embedding of its
mirror caption (every side word swapped),

    e'(s) = e(s) + alpha * (e(s) - e(mirror(s))),

which leaves every caption without a side word exactly as it was (e(s) = e(mirror(s))) and
scales the left/right difference by 1 + alpha. The mirror of a mirror is the caption itself, so
e'(left) - e'(right) = (1 + 2 alpha) (e(left) - e(right)).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from torch import Tensor

SIDES_SUFFIX = "+sides"  # a text encoder spec ending so ("minilm+sides") contrasts the sides
# alpha = 4 puts the two sides of a sentence 0.19 x 9 = 1.7 apart, about as far as two actions.
SIDE_CONTRAST = 4.0
# The mirror rule's version, in the embedding cache's key: 2 leaves "right" alone where it names
# no side ("a right angle"); version 1 swapped it.
MIRROR_VERSION = 2

# Each word and its mirror; "clockwise" is seen from above (the benchmark's captions use both).
_MIRROR = {"left": "right", "right": "left", "clockwise": "counterclockwise",
           "counterclockwise": "clockwise", "anticlockwise": "clockwise"}
# "right" that names no side: "a right angle" ("a right-angle turn to the left" is a left
# turn), "all right", "right away", "right now". Both words are held to the same rule so that the
# mirror of a mirror stays the caption.
_NOT_A_SIDE_BEFORE = r"(?<!\ball\s)"
_NOT_A_SIDE_AFTER = r"(?![-\s]+angle)(?!\s+(?:away|now)\b)"
_WORD = re.compile(_NOT_A_SIDE_BEFORE + r"\b(" + "|".join(sorted(_MIRROR, key=len, reverse=True))
                   + r")\b" + _NOT_A_SIDE_AFTER, re.IGNORECASE)


def mirror_sides(text: str) -> str:
    """The caption with every side word swapped ("left" <-> "right"), capitals kept."""
    def swap(match: re.Match[str]) -> str:
        word = match.group(0)
        mirrored = _MIRROR[word.lower()]
        if word.isupper():
            return mirrored.upper()
        return mirrored.capitalize() if word[0].isupper() else mirrored
    return _WORD.sub(swap, text)


def contrast_sides(texts: list[str], embeddings: Tensor,
                   encode: Callable[[list[str]], Tensor], alpha: float = SIDE_CONTRAST) -> Tensor:
    """(B, D) embeddings of texts -> the side-contrasted embeddings; `encode` embeds the mirror
    captions (only of the texts that name a side, in one batch). A torch tensor or a numpy
    array, and the same kind back."""
    mirrors = [mirror_sides(t) for t in texts]
    sided = [i for i, (t, m) in enumerate(zip(texts, mirrors)) if t != m]
    if not sided:
        return embeddings
    mirrored = encode([mirrors[i] for i in sided])  # (S, D)
    out = embeddings.copy() if hasattr(embeddings, "copy") else embeddings.clone()
    out[sided] = embeddings[sided] + alpha * (embeddings[sided] - mirrored)
    return out
