"""The Python API refuses bad arguments with mlct's own one-line error naming the argument
(issue 15): nothing deep inside torch or numpy reaches the caller, nothing is silently cut."""

from __future__ import annotations

import math

import pytest

import mlct
from mlct.errors import MlctError


@pytest.fixture(scope="module")
def pipe():
    return mlct.load()


@pytest.mark.parametrize("kwargs, names", [
    ({"texts": None}, "texts"),
    ({"texts": 123}, "texts"),
    ({"texts": {"a": 1}}, "texts"),
    ({"texts": ["a person walks", 5]}, "prompt"),
    ({"lengths": 1.5}, "lengths"),
    ({"lengths": math.nan}, "lengths"),
    ({"lengths": "40"}, "lengths"),
    ({"lengths": True}, "lengths"),
    ({"lengths": [40, "x"]}, "lengths"),
    ({"lengths": 0}, "length"),
    ({"lengths": 10**9}, "length"),
    ({"seconds": "3"}, "seconds"),
    ({"seconds": -1.0}, "seconds"),
    ({"seconds": 12.0}, "several prompts.*chained"),
    ({"seconds": math.inf}, "seconds"),
    ({"seconds": [2.0, None]}, "seconds"),
    ({"nfe": 2.7}, "nfe"),
    ({"nfe": "5"}, "nfe"),
    ({"nfe": 0}, "nfe"),
    ({"nfe": 10**6}, "nfe"),
    ({"seed": 1.5}, "seed"),
    ({"seed": 2**70}, "seed"),
    ({"seed": -1}, "seed"),
    ({"seed": "abc"}, "seed"),
    ({"seed": [1, 2.5]}, "seed"),
    ({"seed": [1, 2]}, "seeds"),
])
def test_generate_names_the_bad_argument(pipe, kwargs: dict, names: str) -> None:
    texts = kwargs.pop("texts", "a person walks forward")
    with pytest.raises(MlctError, match=names):
        pipe.generate(texts, **kwargs)


@pytest.mark.parametrize("args, kwargs, names", [
    ((123,), {}, "path"),
    ((), {"device": "bogus"}, "device"),
    ((), {"dtype": "int4"}, "dtype"),
])
def test_load_names_the_bad_argument(args: tuple, kwargs: dict, names: str) -> None:
    with pytest.raises(MlctError, match=names):
        mlct.load(*args, **kwargs)


def test_a_valid_call_still_works(pipe) -> None:
    out = pipe.generate(["a person walks forward"], lengths=[20], nfe=2, seed=2**63 - 1)
    assert out[0].joints.shape == (20, 22, 3) and out[0].seed == 2**63 - 1


def test_text_memo_is_bounded_and_keeps_recent_texts(monkeypatch) -> None:
    """A server sees unboundedly many prompts: the embedding memo is an LRU (issue 15)."""
    import torch

    from mlct.generate import pipeline

    gen = mlct.load()
    calls: list[list[str]] = []

    class Counting:
        def encode(self, texts):
            calls.append(list(texts))
            return torch.stack([torch.full((gen.meta["text_dim"],), float(len(t)))
                                for t in texts])

    gen._text_encoder = Counting()
    monkeypatch.setattr(pipeline, "TEXT_MEMO_SIZE", 2)
    gen.encode_text(["a", "bb"])
    gen.encode_text(["a"])  # "a" becomes the most recent; "bb" the oldest
    out = gen.encode_text(["ccc", "a"])  # "bb" is dropped, "a" kept
    assert calls == [["a", "bb"], ["ccc"]] and list(gen._text_memo) == ["ccc", "a"]
    assert out[0, 0] == 3 and out[1, 0] == 1
    gen.encode_text(["bb"])
    assert calls[-1] == ["bb"] and len(gen._text_memo) == 2
