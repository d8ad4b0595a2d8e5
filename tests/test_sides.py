"""Side contrast (text/sides.py): captions that name a side move away from their mirror."""

from __future__ import annotations

import pytest
import torch

from mlct.text.sides import SIDE_CONTRAST, contrast_sides, mirror_sides


@pytest.mark.parametrize("text, mirrored", [
    ("a person waves with the left hand", "a person waves with the right hand"),
    ("Left foot, then RIGHT foot", "Right foot, then LEFT foot"),
    ("turns clockwise then counterclockwise", "turns counterclockwise then clockwise"),
    ("walks anticlockwise", "walks clockwise"),
    ("a left-handed throw", "a right-handed throw"),
    # no side word: only whole words count
    ("the leftover outright rightful cleft", "the leftover outright rightful cleft"),
    ("", ""),
    # "right" naming no side stays; the side named beside it is swapped
    ("the robot turns by a right angle, toward the left",
     "the robot turns by a right angle, toward the right"),
    ("a Right-Angle turn to the left", "a Right-Angle turn to the right"),
    ("all right, he waves the left hand right now", "all right, he waves the right hand right now"),
    ("turns right away", "turns right away"),
    ("walks right, then angles left", "walks left, then angles right"),
    ("a ball right of him", "a ball left of him"),
])
def test_mirror_sides(text: str, mirrored: str) -> None:
    assert mirror_sides(text) == mirrored


def test_mirror_of_mirror_is_the_caption() -> None:
    for text in ("kicks with the Left leg", "turns right, then left", "jumps",
                 "a left angle, all left, left away"):
        assert mirror_sides(mirror_sides(text)) == text


def _bag_of_words(texts: list[str]) -> torch.Tensor:
    """A stand-in encoder: one count per vocabulary word, so sides show as distinct axes."""
    vocab = ["left", "right", "wave", "jump"]
    return torch.tensor([[float(t.split().count(w)) for w in vocab] for t in texts])


def test_contrast_scales_the_side_difference_and_leaves_the_rest() -> None:
    texts = ["wave left", "wave right", "jump", "jump jump"]
    calls: list[list[str]] = []

    def encode(batch: list[str]) -> torch.Tensor:
        calls.append(batch)
        return _bag_of_words(batch)

    plain = _bag_of_words(texts)
    out = contrast_sides(texts, plain, encode, alpha=2.0)
    assert calls == [["wave right", "wave left"]]  # only the sided captions, one batch
    assert torch.equal(out[2:], plain[2:])
    # e'(L) - e'(R) = (1 + 2 alpha) (e(L) - e(R))
    torch.testing.assert_close(out[0] - out[1], 5.0 * (plain[0] - plain[1]))
    assert torch.equal(plain, _bag_of_words(texts))  # the input is not written into


def test_no_sided_caption_encodes_nothing_more() -> None:
    def encode(batch: list[str]) -> torch.Tensor:
        raise AssertionError("nothing to mirror")

    plain = _bag_of_words(["jump", "wave"])
    assert contrast_sides(["jump", "wave"], plain, encode) is plain


def test_minilm_sides_spec() -> None:
    pytest.importorskip("tokenizers")
    from mlct.text.encoders import load_text_encoder

    texts = ["a person waves with the left hand", "a person waves with the right hand",
             "a person claps"]
    plain = load_text_encoder("minilm").encode(texts)
    sided = load_text_encoder("minilm+sides")
    assert sided.name == "minilm+sides" and sided.dim == 384
    out = sided.encode(texts)
    torch.testing.assert_close(out[2], plain[2])
    # the pooled MiniLM puts the sides ~0.2 apart; contrasted, they are 1 + 2 alpha times that
    gap, contrasted = (plain[0] - plain[1]).norm(), (out[0] - out[1]).norm()
    assert gap < 0.3
    torch.testing.assert_close(contrasted, (1 + 2 * SIDE_CONTRAST) * gap, rtol=1e-4, atol=1e-5)
