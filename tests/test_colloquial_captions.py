"""The colloquial caption vocabulary: truthful captions in the forms held-out set 2 failed on
(rarer verbs, turn sizes in words, a side after its noun, negation), and `mlct data rephrase
--vocabulary colloquial`."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mlct.data.layout import DatasetLayout
from mlct.data.synth.colloquial import (_ADDRESSEES, _PLACES, COLLOQUIAL, COLLOQUIAL_VERBS,
                                        CONTEXT, CONTEXT_SHARE, FORMS)
from mlct.data.synth.rephrase import rephrase_dataset
from mlct.data.synth.text import FAMILIES, describe
from test_everyday import captions_in, make_benchmark
from test_synth_text import act, param_grid, random_motion

# Counts said as numbers; "one" is left out: "one knee, the left one" names a limb, not a count.
COUNTS = {1: r"once|single", 2: r"twice|two|\b2\b", 3: r"three|\b3\b", 4: r"four|\b4\b",
          5: r"five|\b5\b"}
# Every turn-size phrase maps to one angle; a caption must name only its own.
SIZES = {45: r"eighth|small turn|slight turn", 90: r"quarter turn|quarter of a turn|right-angle|"
         r"is now in front", 135: r"sharp turn|more than a quarter", 180: r"half turn|half a turn|"
         r"about-face|way they came|all the way round"}
# a turn said without its size ("turns left without stepping away") is a quarter turn


def colloquial(actions: list, seeds: int = 12, vocabulary=COLLOQUIAL, **kw: object) -> list[str]:
    return captions_in(vocabulary, actions, seeds, **kw)


@pytest.mark.parametrize("vocabulary", [COLLOQUIAL, CONTEXT], ids=["colloquial", "context"])
@pytest.mark.parametrize("family", FAMILIES)
def test_colloquial_captions_state_no_wrong_side_count_angle_or_speed(family: str,
                                                                      vocabulary) -> None:
    for params in param_grid(family):
        caps = colloquial([act(family, **params)], vocabulary=vocabulary)
        said = " | ".join(caps)
        assert all(not re.search(r"[<>]|\bHIS\b|\s,|\s\s|\ba arm|\ba [aeiou]", c)
                   for c in caps), said
        for key, value in params.items():
            if key in ("side", "hand", "leg") and value in ("left", "right"):
                other = "right" if value == "left" else "left"
                wrong_turn = r"\bclockwise" if value == "left" else "counterclockwise"
                named = re.findall(r"\b(left|right)(?!-angle)", said)
                # never the other side, not even of the idle limb: the side-contrast encoder
                # reads any side word as the motion's side
                named_other = [c for c in caps if re.search(rf"\b{other}\b(?!-angle)", c)]
                assert value in named and not named_other, (params, said)
                assert not re.search(wrong_turn, said), (params, said)
            elif key == "hand":  # both: no single side named
                assert not re.search(r"\b(left|right)\b", said), said
            elif key in ("count", "steps"):
                stated = [{n for n, words in COUNTS.items() if re.search(rf"\b({words})", c)}
                          for c in caps]
                assert all(s <= {value} for s in stated), (params, said)
            elif key == "angle":
                for c in caps:
                    # 135 said between its neighbours: "more than a quarter turn but less than a
                    # half turn" names the two it lies between
                    c = c.replace("more than a quarter turn but less than a half turn", "sharp turn")
                    sizes = {a for a, words in SIZES.items() if re.search(words, c)}
                    assert sizes <= {value}, (params, c)
                    assert sizes or value == 90, (params, c)
                    # the benchmark's convention: a bare "turns left" is a quarter turn
                    bare = re.search(r"turn(s|ing) (to the )?(left|right)\b(?! by)", c)
                    assert not bare or value == 90, (params, c)
            elif key == "speed" and family == "walk":
                slow = [c for c in caps if re.search(r"saunter|plod|trudg|slow|hurry", c)]
                fast = [c for c in caps if re.search(r"strid|march|quick|brisk|fast", c)]
                assert (bool(slow), bool(fast)) == {"slow": (True, False),
                                                    "normal": (False, False),
                                                    "fast": (False, True)}[value], (params, said)
        if family in ("walk", "jog", "run"):
            assert not re.search(r"\bback", said), said
        if family not in ("turn", "spin", "circle"):
            # a turn word, negated or not, only of motions that turn: "steps backwards without
            # turning round" made the pooled vector of "turning" mean no turn (docs/training.md)
            turn_word = r"\b(turn\w*|round|around|rotat\w*|pivot\w*|spin\w*|whirl\w*|twirl\w*)\b"
            assert not re.search(turn_word, said), said
        if family == "walk_backward":
            assert all(re.search(r"back", c) for c in caps), said


def test_colloquial_captions_carry_the_four_forms_held_out_set_2_failed_on() -> None:
    turns = colloquial([act("turn", side="left", angle=90)], seeds=40)
    assert sum("quarter" in c for c in turns) >= 10  # a turn's size in words
    kneels = colloquial([act("kneel", leg="right")], seeds=20)
    assert any(re.search(r"knee, the right", c) for c in kneels)  # the side after its noun
    stands = colloquial([act("stand")], seeds=20)
    assert any(re.search(r"does not move|doesn't move|not moving", c) for c in stands)
    steps = colloquial([act("side_step", side="left", steps=2)], seeds=20)
    assert any("sidles" in c or "sidling" in c for c in steps)  # a rarer verb


def test_context_captions_carry_places_and_addressees_and_keep_the_side() -> None:
    context = re.compile("|".join(re.escape(c.replace("HIS ", "")).replace(r"to\ ", r"to\ \w*\ ?")
                                  for c in _PLACES + _ADDRESSEES))
    waves = colloquial([act("wave", hand="left", count=2)], seeds=60, vocabulary=CONTEXT)
    with_context = [c for c in waves if context.search(c)]
    assert 0.5 * CONTEXT_SHARE < len(with_context) / len(waves) < 1.5 * CONTEXT_SHARE
    assert any(re.search(r"(to|for|at|across) [\w ]+, [\w ]*left", c) for c in with_context), \
        with_context  # an addressee before the clause that names the side
    walks = colloquial([act("walk", speed="normal", direction="forward", steps=4)], seeds=60,
                       vocabulary=CONTEXT)
    assert not any(re.search("|".join(map(re.escape, _ADDRESSEES[:1] + _ADDRESSEES[2:])), c)
                   for c in walks)  # addressees only with the actions one does for someone
    assert any(re.search("|".join(map(re.escape, _PLACES)), c) for c in walks)
    # the plain vocabulary is unchanged by the context one (its datasets stay reproducible)
    assert not any(context.search(c) for c in colloquial([act("wave", hand="left", count=2)],
                                                         seeds=60))


def test_colloquial_sentences_conjugate_negations_and_new_verbs() -> None:
    rng = np.random.default_rng(0)
    made = set()
    for _ in range(300):
        actions, concurrent = random_motion(rng)
        made.update(describe(actions, rng, concurrent=concurrent, vocabulary=COLLOQUIAL))
    text = " ".join(made)
    assert not re.search(r"<|>|\bHIS\b|doing not\b|is does|does not moving", text)
    used = {v for v in COLLOQUIAL_VERBS if re.search(rf"\b({v}|{'|'.join(FORMS[v])})\b", text)}
    assert len(used) >= 20, sorted(used)


def test_rephrase_with_the_colloquial_vocabulary(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    summary = rephrase_dataset(src, tmp_path / "coll", per_motion=2, vocabulary="colloquial")
    train = DatasetLayout.existing(src).read_split("train")
    assert summary == {"motions": len(train), "captions": 2 * len(train)}
    meta = json.loads((tmp_path / "coll" / "synth.json").read_text())
    assert meta["rephrased"]["vocabulary"] == "colloquial"
    run = [sys.executable, "-m", "mlct.cli", "data", "rephrase", str(src), "--vocabulary",
           "colloquial", "--out", str(tmp_path / "coll2")]
    done = subprocess.run(run, capture_output=True, text=True)
    assert done.returncode == 0 and "colloquial captions added" in done.stdout
