"""Prompts that name actions in sequence: split into parts, made one part each, chained."""

from __future__ import annotations

import re

import numpy as np
import torch
import pytest

import mlct
from mlct.generate.compose.actions import in_order, split_actions, split_concurrent
from mlct.generate.compose.durations import split_frames
from mlct.generate.compose.long_motion import LongMotion


@pytest.mark.parametrize("text, parts", [
    ("a person walks forward, then waves with the right hand",
     ["a person walks forward", "a person waves with the right hand"]),
    ("someone squats down and then jumps up", ["someone squats down", "someone jumps up"]),
    ("the man waves four times and after that steps to the right, and then jogs forward.",
     ["the man waves four times", "the man steps to the right", "the man jogs forward"]),
    ("a person jumps. Afterwards they bow", ["a person jumps", "they bow"]),
    ("walks forward then turns left", ["walks forward", "a person turns left"]),
    ("a man turns slightly left after sitting down", ["a man sits down",
                                                      "a man turns slightly left"]),
    # listed with commas or "and": a verb we know starts the next action
    ("the person claps three times and jabs with the right arm twice.",
     ["the person claps three times", "the person jabs with the right arm twice"]),
    ("a man punches twice, jogs straight ahead, after that walks backwards.",
     ["a man punches twice", "a man jogs straight ahead", "a man walks backwards"]),
    ("a person turns around to the left and quickly walks forward",
     ["a person turns around to the left", "a person quickly walks forward"]),
    ("a woman is spinning around to the left and pacing forward.",
     ["a woman is spinning around to the left", "a woman paces forward"]),
    # ... unless it completes the action before it
    ("a man squats down and stands back up and bends forward and straightens up, then hops",
     ["a man squats down and stands back up", "a man bends forward and straightens up",
      "a man hops"]),
    # standing back up after going down completes that action; what follows it is a part
    ("a person kneels, then stands and claps", ["a person kneels, then stands", "a person claps"]),
    ("a person pretends to sit on a chair, then stands",
     ["a person pretends to sit on a chair, then stands"]),
    ("a man crouches, then gets back up, then jogs forward",
     ["a man crouches, then gets back up", "a man jogs forward"]),
    ("someone bends down, then straightens up and waves",
     ["someone bends down, then straightens up", "someone waves"]),
    ("a person walks forward, then stands still", ["a person walks forward", "a person stands still"]),
    ("a person squats, then jumps", ["a person squats", "a person jumps"]),
    # standing still after going down is the stand action, not the return
    ("a man squats two times, then stands quietly, then lifts his right arm",
     ["a man squats two times", "a man stands quietly", "a man lifts his right arm"]),
    ("the figure bows forward, then stands in place",
     ["the figure bows forward", "the figure stands in place"]),
    ("someone kneels, then gets back up again, then walks",
     ["someone kneels, then gets back up again", "someone walks"]),
    ("she balances on the left leg and hops twice and does three jumps",
     ["she balances on the left leg and hops twice", "she does three jumps"]),
    # an adverb before the gerund of an after/before clause
    ("a woman turns around before rapidly pacing forward.",
     ["a woman turns around", "a woman rapidly paces forward"]),
    ("a person spins to the right before bowing.", ["a person spins to the right",
                                                    "a person bows"]),
])
def test_sequences_split_into_parts_with_a_subject(text: str, parts: list[str]) -> None:
    assert split_actions(text) == parts


@pytest.mark.parametrize("text", [
    "a person walks forward",
    "a man turns slightly left after that",  # 'after that' + nothing: no second action
    "someone walks backward while waving both arms",  # at once, not in sequence
    "a person squats down and stands back up",  # 'and' + a verb that completes the action
    "a woman raises her arms above her head and bends to one side",  # one stretch
    "a person walks forward and back",  # 'back' is a direction here
    "a man stands on his left leg and hops",  # standing first: the action that follows
    "a person bends the knees and drops low",  # one squat
    "a man walks forward and waves at the same time",  # at once: split_concurrent's
    "a person turns three hundred and sixty degrees",  # no verb after 'and'
    "a person walks to the next room",
    "Then a person jumps",  # nothing before the sequencing word
    "a person claps, followed by a bow",  # a noun phrase follows: no prompt of its own
    "the athlete strengthens his legs",  # 'then' inside a word
    # going down, then only coming back up: one action
    "an old lady lowers herself onto a bench and then gets up again",
    "a man sits on a stool for a moment, then rises to his feet",
    "a girl lowers onto her left knee, then rises.",
    "a man gets down on his right knee, then gets up",
    "the runner stretches with arms overhead, leaning left and then right",  # one lean
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
    # the parts share the 120 frames by their predicted durations (the bundled durations.json)
    assert pipe.durations is not None
    weights = pipe.durations.part_weights(pipe.encode_text(list(chained.texts)).numpy(), 6.0, 1.0)
    share = split_frames(weights, 120, 20)
    assert share[0] != 60 and sum(share) == 120
    assert chained.joints.shape[0] == 120 and chained.seams == (share[0],)
    assert chained.features.shape[1] == 263 and chained.seed == 0
    # the part made alone, at its own seed, is the chain's first part (as decoded: the chain
    # plants its feet once, as a whole)
    lock, pipe.foot_lock = pipe.foot_lock, None
    try:
        first = pipe.generate("a person walks forward", lengths=share[0] + chained.blend,
                              seed=0, split_actions=False)[0]
    finally:
        pipe.foot_lock = lock
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


@pytest.mark.parametrize("text, body, arms", [
    ("a man walks forward while waving his right hand twice", "a man walks forward",
     "a man waves his right hand twice"),
    ("a person waves his left hand while walking forward", "a person walks forward",
     "a person waves his left hand"),
    ("a woman jogs forward and claps her hands at the same time", "a woman jogs forward",
     "a woman claps her hands"),
    ("a man walks forward while raising his right arm and waving, then turns left",
     "a man walks forward, then turns left", "a man raises his right arm and waves"),
    ("a person turns left, then walks forward while clapping",
     "a person turns left, then walks forward", "a person claps"),
    ("walks backward while punching with the left hand", "walks backward",
     "a person punches with the left hand"),
    # an adverb or "is" before the verb, a final period after "at the same time"
    ("someone quickly walks ahead and claps five times at the same time.",
     "someone quickly walks ahead", "someone claps five times"),
    ("the person is slowly walking ahead and punching with their right fist at the same time.",
     "the person is slowly walking ahead", "the person punches with their right fist"),
    ("a figure is raising both hands up while walking forward.", "a figure walks forward",
     "a figure is raising both hands up"),
])
def test_an_arm_action_at_the_same_time_is_split_off(text: str, body: str, arms: str) -> None:
    assert split_concurrent(text) == (body, arms)


@pytest.mark.parametrize("text", [
    "a person walks forward", "a person waves while smiling",  # an unknown verb: one action
    "a person walks while thinking", "a person waves while clapping",  # both or neither arms
    "a person walks forward, then waves",  # a sequence, not at the same time
])
def test_no_concurrent_arm_action(text: str) -> None:
    assert split_concurrent(text) is None


def test_a_concurrent_arm_action_is_grafted_on_the_body(pipe) -> None:
    text = "a person walks forward while waving his right hand"
    made = pipe.generate(text, seconds=5, seed=0)[0]
    body = pipe.generate("a person walks forward", seconds=5, seed=0)[0]
    arms = [pipe.skeleton.index(n) for n in ("left_shoulder", "right_shoulder", "left_elbow",
                                             "right_elbow", "left_wrist", "right_wrist")]
    rest = [j for j in range(pipe.skeleton.n_joints) if j not in arms
            and pipe.skeleton.joint_names[j] not in ("left_collar", "right_collar")]
    assert made.text == text and made.joints.shape == body.joints.shape
    np.testing.assert_allclose(made.joints[:, rest], body.joints[:, rest], atol=1e-5)
    # the arms are the wave's: the right wrist goes above the head, which walking never does
    head = pipe.skeleton.index("head")
    wrist = pipe.skeleton.index("right_wrist")
    assert (made.joints[:, wrist, 1] - made.joints[:, head, 1]).max() > 0.0
    assert (body.joints[:, wrist, 1] - body.joints[:, head, 1]).max() < -0.2
    whole = pipe.generate(text, seconds=5, seed=0, split_actions=False)[0]
    assert not np.allclose(whole.joints, made.joints, atol=1e-3)


@pytest.mark.parametrize("text, ordered", [
    ("a man turns left after walking forward", "a man walks forward, then turns left"),
    ("after turning right, someone kicks twice", "someone turns right, then kicks twice"),
    ("the figure leaps ahead before making a sharp right turn.",
     "the figure leaps ahead, then makes a sharp right turn"),
    ("before doing three jumps, a person kicks", "a person kicks, then does three jumps"),
    ("a man walks forward, then turns left before jumping",
     "a man walks forward, then turns left, then jumps"),
    # no action in the clause, or no clause: unchanged
    ("a man walks to the door before the storm", "a man walks to the door before the storm"),
    ("a figure moves backwards, after that squats.", "a figure moves backwards, after that squats."),
])
def test_after_and_before_clauses_are_put_in_order(text: str, ordered: str) -> None:
    assert in_order(text) == ordered


def test_a_clause_splits_into_actions_in_order() -> None:
    assert split_actions("a man turns left after walking forward") == [
        "a man walks forward", "a man turns left"]


@pytest.mark.parametrize("text, read", [
    ("a figure skater pirouettes to the right", "a person pirouettes to the right"),
    ("the robot stays motionless, not moving a muscle", "a person stays motionless, not moving a muscle"),
    ("a tired woman sinks into a chair", "a person sinks into a chair"),
    # "dress" ends in s but is no verb; the subject runs to "twirls", seven words long
    ("a little girl in a party dress twirls all the way round",
     "a person twirls all the way round"),
    ("a man in a woolly hat waves", "a person waves"),  # "woolly" is not an adverb
    ("a nervous man proposing in a restaurant gets down on one knee",  # "nervous" is no verb
     "a person gets down on one knee"),
    ("a man with his dog walks forward", "a person walks forward"),  # nor is "his"
    # a word after "the" is a noun: "stands" is not the verb
    ("a fan in the stands waves both hands", "a person in the stands waves both hands"),
    ("he walks forward", "a person walks forward"),
    ("an old man claps twice", "an old man claps twice"),  # a subject the captions use
    ("The Woman jumps", "The Woman jumps"),
    ("the left arm rises", "the left arm rises"),  # a body part, not who moves
    ("a man power walks", "a man power walks"),  # a trained subject's further words stay
    ("a person side shuffles to the right", "a person side shuffles to the right"),
    ("walks forward, then waves", "walks forward, then waves"),  # no subject
])
def test_a_subject_the_captions_never_used_is_read_as_a_person(text: str, read: str) -> None:
    from mlct.generate.compose.actions import plain_subject

    assert plain_subject(text) == read


def test_the_generator_reads_unknown_subjects_as_a_person() -> None:
    import mlct

    pipe = mlct.load()
    a, b, c = pipe.encode_text(["the robot waves", "a person waves", "a man waves"])
    assert torch.equal(a, b) and not torch.equal(b, c)


def test_verbose_says_how_each_prompt_is_read(tmp_path, capsys):
    """--verbose logs each prompt's parts as the text encoder gets them, with the text anchors'
    pull where there is one; without it stderr says nothing of the kind, also after a call with
    it in the same process."""
    from mlct.cli import main

    far = "a little girl in a party dress twirls all the way round on the spot"
    assert main(["generate", far, "--seconds", "2", "--seed", "0", "--backend", "torch",
                 "--candidates", "1", "--verbose", "--out", str(tmp_path / "f.npy")]) == 0
    err = capsys.readouterr().err
    assert (f"{far!r} read as 'a person twirls all the way round on the spot' (pulled 0.50 "
            "towards the training captions)") in err
    text = "the robot walks forward while clapping, then sits down"
    assert main(["generate", text, "--seconds", "4", "--seed", "0", "--backend", "torch",
                 "--candidates", "1", "--verbose", "--out", str(tmp_path / "s.npy")]) == 0
    err = capsys.readouterr().err
    assert (f"{text!r} read as 'a person walks forward', then 'a person sits down'; its arms "
            "as 'a person claps'") in err
    # and what it took, the text encoder apart
    assert re.search(r"mlct: 1 motion made in \d+\.\d ms, the text encoder \d+\.\d ms before "
                     r"\(backend torch; writing not counted\)", err), err
    assert main(["generate", "a person walks forward", "a person jumps", "--seconds", "2", "1",
                 "--seed", "0", "--backend", "torch", "--candidates", "1", "--verbose",
                 "--out", str(tmp_path / "two.npy")]) == 0
    assert re.search(r"mlct: 1 motion of 2 parts made in \d+\.\d ms \(backend torch",
                     capsys.readouterr().err)
    assert main(["generate", text, "--seconds", "4", "--seed", "0", "--backend", "torch",
                 "--candidates", "1", "--out", str(tmp_path / "q.npy")]) == 0
    err = capsys.readouterr().err
    assert "read as" not in err and "made in" not in err


def test_reading_says_how_generate_reads_a_prompt(pipe) -> None:
    """pipe.reading: one entry per sample generate() makes of the prompt, each as the text
    encoder gets it, with the text anchors' pull and whether the model knows it."""
    got = pipe.reading("the robot walks forward while clapping, then sits down")
    assert got == [
        {"part": "the robot walks forward", "read_as": "a person walks forward", "pull": 0.0,
         "arms": False, "known": True},
        {"part": "the robot sits down", "read_as": "a person sits down", "pull": 0.0,
         "arms": False, "known": True},
        {"part": "the robot claps", "read_as": "a person claps", "pull": 0.0, "arms": True,
         "known": True}]
    far = pipe.reading("a little girl in a party dress twirls all the way round on the spot")
    assert [p["read_as"] for p in far] == ["a person twirls all the way round on the spot"]
    assert 0.0 < far[0]["pull"] <= 1.0
    whole = pipe.reading("a person walks forward, then waves", split_actions=False)
    assert [p["part"] for p in whole] == ["a person walks forward, then waves"]
    from mlct.errors import MlctError

    with pytest.raises(MlctError):
        pipe.reading("   ")
