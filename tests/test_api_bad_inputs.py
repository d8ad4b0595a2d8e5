"""The Python API around its bad arguments. The bad arguments themselves, each
refused with mlct's one-line error naming the argument, are tables in test_bad_inputs.py; here:
a valid call at the edges still works, and the text memo stays bounded."""

from __future__ import annotations

import pytest

import mlct


@pytest.fixture(scope="module")
def pipe():
    return mlct.load()


def test_a_valid_call_still_works(pipe) -> None:
    out = pipe.generate(["a person walks forward"], lengths=[20], nfe=2, seed=2**63 - 1)
    assert out[0].joints.shape == (20, 22, 3) and out[0].seed == 2**63 - 1


def test_text_memo_is_bounded_and_keeps_recent_texts(monkeypatch) -> None:
    """A server sees unboundedly many prompts: the embedding memo is an LRU."""
    import torch

    from mlct.generate import core

    gen = mlct.load()
    calls: list[list[str]] = []

    class Counting:
        def encode(self, texts):
            calls.append(list(texts))
            return torch.stack([torch.full((gen.meta["text_dim"],), float(len(t)))
                                for t in texts])

    gen.networks._text_encoder = Counting()
    monkeypatch.setattr(core, "TEXT_MEMO_SIZE", 2)
    gen.encode_text(["a", "bb"])
    gen.encode_text(["a"])  # "a" becomes the most recent; "bb" the oldest
    out = gen.encode_text(["ccc", "a"])  # "bb" is dropped, "a" kept
    assert calls == [["a", "bb"], ["ccc"]] and list(gen.core._text_memo) == ["ccc", "a"]
    assert out[0, 0] == 3 and out[1, 0] == 1
    gen.encode_text(["bb"])
    assert calls[-1] == ["bb"] and len(gen.core._text_memo) == 2
