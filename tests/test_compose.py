"""Prompts that name actions in sequence: split into parts, made one part each, chained."""

from __future__ import annotations

import numpy as np
import pytest

import mlct
from mlct.generate.compose import split_actions
from mlct.generate.long_motion import LongMotion


@pytest.mark.parametrize("text, parts", [
    ("a person walks forward, then waves with the right hand",
     ["a person walks forward", "a person waves with the right hand"]),
    ("someone squats down and then jumps up", ["someone squats down", "someone jumps up"]),
    ("the man waves four times and after that steps to the right, and then jogs forward.",
     ["the man waves four times", "the man steps to the right", "the man jogs forward"]),
    ("a person jumps. Afterwards they bow", ["a person jumps", "they bow"]),
    ("walks forward then turns left", ["walks forward", "a person turns left"]),
])
def test_sequences_split_into_parts_with_a_subject(text: str, parts: list[str]) -> None:
    assert split_actions(text) == parts


@pytest.mark.parametrize("text", [
    "a person walks forward",
    "a man turns slightly left after sitting down",  # order would need parsing: kept whole
    "someone walks backward while waving both arms",  # at once, not in sequence
    "a person turns around and walks back",  # 'and' alone: often one action
    "a person walks to the next room",
    "Then a person jumps",  # nothing before the sequencing word
    "a person claps, followed by a bow",  # a noun phrase follows: no prompt of its own
    "the athlete strengthens his legs",  # 'then' inside a word
])
def test_single_actions_stay_whole(text: str) -> None:
    assert split_actions(text) == [text]


@pytest.fixture(scope="module")
def pipe():
    return mlct.load()


def test_a_sequence_is_chained_from_its_parts(pipe) -> None:
    text = "a person walks forward, then squats"
    out = pipe.generate([text, "a person jumps"], seconds=[6, 3], seed=0)
    chained, plain = out[0], out[1]
    assert isinstance(chained, LongMotion) and not isinstance(plain, LongMotion)
    assert chained.text == text and chained.texts == ("a person walks forward",
                                                      "a person squats")
    assert chained.joints.shape[0] == 120 and chained.seams == (60,)
    assert chained.features.shape[1] == 263 and chained.seed == 0
    # the part made alone, at its own seed, is the chain's first part
    first = pipe.generate("a person walks forward", lengths=60 + chained.blend, seed=0,
                          split_actions=False)[0]
    np.testing.assert_allclose(chained.segments[0], first.joints, atol=1e-4)
    # the item beside it is what it would be alone (seed 0 + 1)
    alone = pipe.generate("a person jumps", seconds=3, seed=1)[0]
    np.testing.assert_allclose(plain.joints, alone.joints, atol=1e-4)


def test_whole_prompt_and_short_motions_are_not_split(pipe) -> None:
    text = "a person walks forward, then squats"
    whole = pipe.generate(text, seconds=6, seed=0, split_actions=False)[0]
    assert not isinstance(whole, LongMotion) and whole.joints.shape[0] == 120
    short = pipe.generate(text, seconds=1.5, seed=0)[0]  # 0.75 s a part: below the minimum
    assert not isinstance(short, LongMotion) and short.joints.shape[0] == 30
