"""Prompts the model does not know are said to be so (generate/compose/unknown_prompts.py): in the
motions generate() returns, on `mlct generate`'s stderr and in POST /generate's reply; the
motions themselves stay as they were."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from fastapi.testclient import TestClient

import mlct
from mlct.cli import main
from mlct.data.synth.build import _split, make_motion
from mlct.generate.compose.text_anchors import TextAnchors
from mlct.generate.compose.unknown_prompts import UNKNOWN_BELOW, unknown_notice, unknown_rows
from mlct.motion.skeleton import get_skeleton
from mlct.serve import ServeSettings, create_app

pytestmark = pytest.mark.usefixtures("one_thread")

GUITAR = "a person plays the guitar"
KNOWN = "a person walks forward at a brisk pace."


@pytest.fixture(scope="module")
def pipe():
    return mlct.load(backend="torch")


def test_the_rule_is_the_nearest_caption_cosine_under_the_threshold():
    # five captions in the first three dimensions, scaled (the cosine ignores it)
    e = torch.eye(4)
    vectors = torch.stack([e[0], e[1], e[2], e[0] + e[1], e[1] + e[2]]) * 3.0
    anchors = TextAnchors(vectors, near=0.9, span=0.2, pull=0.5)
    on_a_caption = torch.tensor([[2.0, 0.0, 0.0, 0.0]])
    angle = np.arccos(UNKNOWN_BELOW)  # just inside and just outside the threshold's cone
    inside = torch.tensor([[np.cos(angle - 0.01), 0.0, 0.0, np.sin(angle - 0.01)]]).float()
    outside = torch.tensor([[np.cos(angle + 0.01), 0.0, 0.0, np.sin(angle + 0.01)]]).float()
    rows = torch.cat([on_a_caption, inside, outside])
    assert anchors.nearest(rows).tolist() == pytest.approx(
        [1.0, np.cos(angle - 0.01), np.cos(angle + 0.01)], abs=1e-6)
    assert unknown_rows(anchors, rows) == [False, False, True]
    # a model's anchors may carry their own threshold
    strict = TextAnchors(vectors, 0.9, 0.2, 0.5, info={"unknown_below": 0.999})
    assert unknown_rows(strict, rows) == [False, True, True]


def test_the_notice_names_the_unknown_part():
    assert unknown_notice(GUITAR, (GUITAR,)).startswith(f"{GUITAR!r} is far from every caption")
    line = unknown_notice("a person walks, then plays the guitar", (GUITAR,))
    assert line.startswith(f"{GUITAR!r} (in 'a person walks, then plays the guitar') is far from")
    assert "\n" not in line


def test_unknown_activities_are_flagged_and_benchmark_captions_are_not(pipe):
    unknown = [GUITAR, "a person lies down on the floor", "a person picks up a box",
               "a person swims freestyle"]
    assert pipe.unknown_parts(unknown) == [(t,) for t in unknown]
    # captions of the benchmark's test motions (the model never saw them) are known: the
    # bundled model's benchmark, version 2
    names = [f"{i:06d}" for i in range(4000)]
    test = _split(names, 0)["test"][:12]
    skeleton = get_skeleton("humanml3d")
    captions = [c for n in test for c in make_motion(int(n), 0, skeleton, 2).label["captions"]]
    assert pipe.unknown_parts(captions) == [()] * len(captions)


def test_a_prompt_of_several_actions_names_its_unknown_one(pipe):
    text = "a person walks forward, then plays the guitar"
    assert pipe.unknown_parts(text) == [(GUITAR,)]
    assert pipe.unknown_parts("a person walks forward, then waves") == [()]
    reading = pipe.reading(text)
    assert [p["known"] for p in reading] == [True, False]
    # made whole, the whole prompt is the one part
    both = f"{GUITAR}, then plays the drums"
    assert pipe.unknown_parts(both) == [(GUITAR, "a person plays the drums")]
    assert pipe.unknown_parts(both, split_actions=False) == [(both,)]


def test_generate_marks_the_motions_and_changes_nothing_else(pipe):
    texts = [GUITAR, KNOWN, "a person walks forward, then plays the guitar"]
    made = pipe.generate(texts, seconds=[2, 2, 3], seed=4, candidates=2)
    assert made.unknown_parts == [(GUITAR,), (), (GUITAR,)]
    assert [m.known for m in made] == [False, True, False]
    judged = pipe.known_anchors
    try:
        pipe.known_anchors = None  # no judgement: the motions as they were made before it
        plain = pipe.generate(texts, seconds=[2, 2, 3], seed=4, candidates=2)
    finally:
        pipe.known_anchors = judged
    assert plain.unknown_parts == [(), (), ()]
    np.testing.assert_array_equal(made.joints, plain.joints)
    assert [m.seed for m in made] == [m.seed for m in plain]
    # judging a prompt the motions never encoded leaves the text memo as it was
    memo = list(pipe.core._text_memo)
    assert pipe.unknown_parts("a person juggles three balls") == [
        ("a person juggles three balls",)]
    assert list(pipe.core._text_memo) == memo
    # a copy keeps what was said of its prompt
    assert made[0].in_place().unknown_parts == (GUITAR,)


def test_the_cli_says_so_in_one_line_without_verbose(tmp_path, capsys):
    out = tmp_path / "g.npy"
    assert main(["generate", GUITAR, "--seconds", "1", "--seed", "0", "--candidates", "1",
                 "--num", "2", "--quiet", "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    # once for --num 2; --quiet hides the progress bar, not this
    assert err == [f"mlct: {unknown_notice(GUITAR, (GUITAR,))}"]
    # the pull turned off, the judgement stays
    assert main(["generate", GUITAR, "--seconds", "1", "--candidates", "1",
                 "--no-text-anchors", "--out", str(out)]) == 0
    assert "far from every caption" in capsys.readouterr().err
    assert main(["generate", KNOWN, "--seconds", "1", "--candidates", "1", "--out",
                 str(out)]) == 0
    assert capsys.readouterr().err == ""
    # --verbose's reading of the prompt says it too
    assert main(["generate", "a person walks forward, then plays the guitar", "--seconds", "4",
                 "--candidates", "1", "--verbose", "--out", str(out)]) == 0
    assert (f"then {GUITAR!r} (pulled 0.50 towards the training captions) (unknown to the "
            "model)") in capsys.readouterr().err


def test_the_cli_names_the_unknown_prompt_of_a_long_motion(tmp_path, capsys):
    assert main(["generate", KNOWN, GUITAR, "--seconds", "2", "2", "--candidates", "1",
                 "--out", str(tmp_path / "long.npy")]) == 0
    assert capsys.readouterr().err.strip().splitlines() == [
        f"mlct: {unknown_notice(GUITAR, (GUITAR,))}"]


def test_the_http_reply_carries_the_unknown_parts(pipe):
    with TestClient(create_app(pipe, ServeSettings(warmup=False))) as client:
        reply = client.post("/generate", json={"texts": [GUITAR, KNOWN], "seconds": 1,
                                               "seed": 2, "candidates": 1, "nfe": 2})
        assert reply.status_code == 200, reply.text
        motions = reply.json()["motions"]
        assert [m["unknown_parts"] for m in motions] == [[GUITAR], []]
        expected = pipe.generate([GUITAR], seconds=1, seed=2, candidates=1, nfe=2)[0].joints
        np.testing.assert_allclose(np.array(motions[0]["joints"]), expected, atol=2e-4)
        file = client.post("/generate", json={"text": GUITAR, "seconds": 1, "seed": 2,
                                              "candidates": 1, "nfe": 2, "format": "npy"})
        assert file.status_code == 200
        assert json.loads(file.headers["x-mlct-unknown-parts"]) == [GUITAR]
