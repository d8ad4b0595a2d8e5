"""A list of prompts is sampled in a few large batches, whatever each prompt becomes
(generate/compose/batch_plan.py), and every motion is the one its prompt makes alone."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

import mlct
from mlct.generate.compose.batch_plan import Sample, planned_samples

MIXED = ["a person walks forward, then waves with the right hand",  # a sequence
         "a person walks forward while waving the left hand",  # a body and its arms
         "a person jumps twice",  # plain
         "someone squats, then claps, then bows"]  # a sequence of three
MIXED_SECONDS = [7.0, 5.0, 4.0, 8.0]


@pytest.fixture(scope="module")
def generator():
    return mlct.load(backend="torch")


class Recorder:
    """Wraps sample_best: the batch size of each call and every item's (row, frames, seed)."""

    def __init__(self, generator) -> None:
        self.generator, self.inner = generator, generator.sample_best
        self.calls: list[int] = []
        self.items: list[tuple[bytes, int, int]] = []

    def __call__(self, cond, seeds, lengths, how):
        self.calls.append(len(seeds))
        self.items += [(np.asarray(row, dtype=np.float32).tobytes(), int(n), int(s))
                       for row, n, s in zip(cond, lengths, seeds)]
        return self.inner(cond, seeds, lengths, how)

    def __enter__(self) -> "Recorder":
        self.generator.sample_best = self
        return self

    def __exit__(self, *exc) -> None:
        del self.generator.sample_best  # the class's method again


def made(generator, texts, seconds, seed, ahead: bool, **kwargs):
    """The motions of texts made as one list (ahead: its samples made in a few batches) or
    one prompt at a time, a call each, with the seeds and seconds the list gives them."""
    with Recorder(generator) as recorder:
        if ahead:
            out = generator.generate(texts, seconds=seconds, seed=seed, **kwargs)
        else:
            each = seconds if isinstance(seconds, list) else [seconds] * len(texts)
            out = [generator.generate(text, seconds=n, seed=seed + i, **kwargs)[0]
                   for i, (text, n) in enumerate(zip(texts, each))]
    return out, recorder


def test_a_mixed_list_is_sampled_in_one_batch_with_the_same_motions(generator):
    out, ahead = made(generator, MIXED, MIXED_SECONDS, 3, True)
    alone, before = made(generator, MIXED, MIXED_SECONDS, 3, False)
    assert ahead.calls == [8]  # 2 parts + body and arms + 1 + 3 parts, one batch
    assert len(before.calls) == 5  # one per prompt's path, the concurrent one two
    assert Counter(ahead.items) == Counter(before.items)  # the same samples asked for
    for a, b in zip(out, alone):
        assert type(a) is type(b) and a.joints.shape == b.joints.shape
        np.testing.assert_allclose(a.joints, b.joints, atol=1e-4)


def test_the_plan_lists_what_the_paths_ask_for(generator):
    fps = generator.skeleton.fps
    frames = [int(round(s * fps)) for s in MIXED_SECONDS]
    plan = planned_samples(generator, MIXED, frames, [3, 4, 5, 6], True)
    texts = sorted({s.text for s in plan})
    rows = dict(zip(texts, generator.encode_text(texts)))
    _, recorder = made(generator, MIXED, MIXED_SECONDS, 3, False)
    assert Counter((rows[s.text].float().numpy().tobytes(), s.frames, s.seed) for s in plan) \
        == Counter(recorder.items)
    # split_actions=False: one sample per prompt, as given
    whole = planned_samples(generator, MIXED, frames, [3, 4, 5, 6], False)
    assert whole == [Sample(t, n, s) for t, n, s in zip(MIXED, frames, [3, 4, 5, 6])]


def test_gaits_that_keep_going_get_their_takes_in_one_batch(generator):
    texts = ["a person jogs forward", "a person walks forward", "a person runs forward"]
    out, ahead = made(generator, texts, 9.0, 0, True, candidates=1)
    alone, before = made(generator, texts, 9.0, 0, False, candidates=1)
    assert all(len(m.seams) >= 1 for m in out)  # each kept going
    assert len(ahead.calls) == 2  # the prompts, then every prompt's takes
    assert len(before.calls) == 6  # each prompt, then its takes
    assert Counter(ahead.items) == Counter(before.items)
    for a, b in zip(out, alone):
        np.testing.assert_allclose(a.joints, b.joints, atol=1e-4)


def test_an_unforeseen_sample_is_still_made(generator):
    """A sample the memo does not hold (other settings than the plan's) is sampled where it is
    asked for: batch_plan.best_features falls through to sample_best."""
    from mlct.generate.compose.batch_plan import SampleMemo
    from mlct.generate.seeds import Sampling

    generator.nesting.memo = SampleMemo(Sampling(generator.check_nfe(None), None, 1))
    try:
        out = generator.generate("a person jumps", seconds=3.0, seed=0, candidates=1)[0]
    finally:
        generator.nesting.memo = None
    alone = generator.generate("a person jumps", seconds=3.0, seed=0, candidates=1)[0]
    np.testing.assert_allclose(out.joints, alone.joints, atol=1e-5)


def test_the_samples_are_made_a_few_dozen_latents_a_call_on_a_cpu(generator, monkeypatch):
    """Past ~64 latents a call the CPU's time per motion grows (the cache), so the memo is
    filled in calls of PREFETCH_LATENTS latents: here 16, two prompts of 8 candidates each."""
    from mlct.generate.compose import batch_plan

    monkeypatch.setitem(batch_plan.PREFETCH_LATENTS, "cpu", 16)
    out, ahead = made(generator, MIXED, MIXED_SECONDS, 3, True)
    assert ahead.calls == [2, 2, 2, 2]
    first, _ = made(generator, MIXED[:1], MIXED_SECONDS[:1], 3, True)
    np.testing.assert_allclose(out[0].joints, first[0].joints, atol=1e-4)
