"""Captions of the procedural benchmark: truthful words, distinct paraphrases, HumanML3D tokens."""

from __future__ import annotations

import itertools
import re
from types import SimpleNamespace

import numpy as np
import pytest

from mlct.data.captions import POS_TAGS, format_text_line, pos_tag
from mlct.data.synth.text import (
    ACTION_PARAMS,
    FAMILIES,
    LOCOMOTION,
    OPTIONAL_PARAMS,
    UPPER_BODY,
    canonical_label,
    describe,
)


def act(family: str, **params: object) -> SimpleNamespace:
    return SimpleNamespace(family=family, params=params)


def param_grid(family: str) -> list[dict]:
    """Every combination of a family's parameter values (optional ones also left out)."""
    spec = ACTION_PARAMS[family]
    grid = [dict(zip(spec, values)) for values in itertools.product(*spec.values())]
    for key in OPTIONAL_PARAMS.get(family, ()):
        grid += [{k: v for k, v in g.items() if k != key} for g in grid if g[key] == "normal"]
    return grid


def captions_of(actions: list, seeds: int = 10, **kw: object) -> list[str]:
    return [c for s in range(seeds) for c in describe(actions, np.random.default_rng(s), **kw)]


COUNT_WORDS = {1: r"once|one|single", 2: r"twice|two|2", 3: r"three|3", 4: r"four|4", 5: r"five|5"}
SLOW = r"\bslow|stroll|leisurely"
FAST = r"quick|brisk|\bfast\b|rapid|hurr"
ANGLE_WORDS = {
    45: r"\b45\b|forty five|slight",
    90: r"\b90\b|ninety|quarter|turn(s|ing) (to the )?(left|right)\b(?! by)|a (left|right) turn",
    135: r"\b135\b|thirty five|sharp",
    180: r"\b180\b|eighty|around|half",
}


def counts_said(caption: str) -> set[int]:
    return {n for n, words in COUNT_WORDS.items() if re.search(rf"\b({words})\b", caption)}


@pytest.mark.parametrize("family", FAMILIES)
def test_every_value_is_stated_truthfully(family: str) -> None:
    for params in param_grid(family):
        caps = captions_of([act(family, **params)])
        said = " | ".join(caps)
        for key, value in params.items():
            if key in ("side", "hand", "leg") and value in ("left", "right"):
                other = "right" if value == "left" else "left"
                own_turn, other_turn = (("counterclockwise", r"\bclockwise") if value == "left"
                                        else (r"\bclockwise", "counterclockwise"))
                assert not re.search(rf"\b{other}\b|{other_turn}", said), (params, said)
                assert re.search(rf"\b{value}\b|{own_turn}", said), (params, said)
            elif key == "hand":  # both
                assert not re.search(r"\b(left|right)\b", said), said
                assert all(re.search(r"\bboth\b|\b(hands|arms)\b", c) for c in caps), said
            elif key in ("count", "steps"):
                for c in caps:
                    assert counts_said(c) <= {value}, (params, c)
                    assert value == 1 or counts_said(c) == {value}, (params, c)
            elif key == "speed":
                slow, fast = (sum(bool(re.search(w, c)) for c in caps) for w in (SLOW, FAST))
                assert (slow, fast) == {"slow": (len(caps), 0), "normal": (0, 0),
                                        "fast": (0, len(caps))}[value], (params, said)
            elif key == "angle":
                for c in caps:
                    assert re.search(ANGLE_WORDS[value], c), (params, c)
                    wrong = [a for a in ANGLE_WORDS if a != value and re.search(ANGLE_WORDS[a], c)]
                    assert not wrong, (params, c)
            elif key == "mode":
                near, far = r"\b(place|spot|up)\b", r"\b(forward|ahead)\b"
                if value == "forward":
                    near, far = far, near
                assert all(re.search(near, c) and not re.search(far, c) for c in caps), said
            elif key == "direction":
                assert all(re.search(r"\b(forward|ahead)\b", c) for c in caps), said
                assert "back" not in said
        if family == "walk_backward":
            assert all(re.search(r"backward|\bback(s|ing)? up|reverse", c) for c in caps), said


def test_three_distinct_captions_deterministic_per_seed() -> None:
    motion = [act("walk", speed="fast", direction="forward"), act("turn", side="left", angle=90)]
    first = describe(motion, np.random.default_rng(3))
    assert len(first) == 3 and len(set(first)) == 3
    assert describe(motion, np.random.default_rng(3)) == first
    assert describe(motion, np.random.default_rng(4)) != first
    many = describe([act("bow")], np.random.default_rng(0), n_captions=8)
    assert len(set(many)) == 8


def random_motion(rng: np.random.Generator) -> tuple[list, object | None]:
    def sample(family: str) -> SimpleNamespace:
        grid = param_grid(family)
        return act(family, **grid[rng.integers(len(grid))])

    actions = [sample(FAMILIES[rng.integers(len(FAMILIES))]) for _ in range(rng.integers(1, 4))]
    concurrent = None
    if any(a.family in LOCOMOTION for a in actions) and rng.random() < 0.3:
        concurrent = sample(sorted(UPPER_BODY)[rng.integers(len(UPPER_BODY))])
    return actions, concurrent


def test_lexicon_covers_everything_generated() -> None:
    rng = np.random.default_rng(0)
    for _ in range(5000):
        actions, concurrent = random_motion(rng)
        for caption in describe(actions, rng, concurrent=concurrent):
            assert caption == caption.lower() and caption.endswith(".")
            assert not re.search(r"[<>]|\bHIS\b|\s,|\s\s", caption), caption
            tags = pos_tag(caption)  # raises on any word outside the lexicon
            words = [w for w in re.findall(r"[a-z0-9]+", caption) if w.isalpha()]
            assert len(tags) == len(words), caption
            assert all(tok.isalpha() and pos in POS_TAGS for tok, pos in tags), (caption, tags)


def tag_string(caption: str) -> str:
    return " ".join(f"{w}/{p}" for w, p in pos_tag(caption))


@pytest.mark.parametrize("caption, expected", [
    ("a person walks forward and then turns left.",
     "a/DET person/NOUN walk/VERB forward/ADV and/CCONJ then/ADV turn/VERB left/ADV"),
    ("the man jumps up twice.", "the/DET man/NOUN jump/VERB up/ADP twice/ADV"),
    ("someone kicks with their left leg.",
     "someone/PRON kick/VERB with/ADP their/DET left/ADJ leg/NOUN"),
    ("a woman does 3 squats, then makes a quarter turn to the right.",
     "a/DET woman/NOUN do/VERB squat/NOUN then/ADV make/VERB a/DET quarter/NOUN turn/NOUN "
     "to/ADP the/DET right/NOUN"),
    ("a person walks forward while waving his right hand.",
     "a/DET person/NOUN walk/VERB forward/ADV while/SCONJ wave/VERB his/DET right/ADJ hand/NOUN"),
    ("the figure is hopping on her left foot three times before sitting down.",
     "the/DET figure/NOUN is/AUX hop/VERB on/ADP her/DET left/ADJ foot/NOUN three/NUM time/NOUN "
     "before/ADP sit/VERB down/ADP"),
    ("someone hurries forward, then does two squats and is hopping before rising.",
     "someone/PRON hurry/VERB forward/ADV then/ADV do/VERB two/NUM squat/NOUN and/CCONJ is/AUX "
     "hop/VERB before/ADP rise/VERB"),
    ("A man walks at a fast pace, then walks fast.",
     "a/DET man/NOUN walk/VERB at/ADP a/DET fast/ADJ pace/NOUN then/ADV walk/VERB fast/ADV"),
])
def test_pos_tag_matches_humanml3d_conventions(caption: str, expected: str) -> None:
    assert tag_string(caption) == expected


def test_pos_tag_rejects_unknown_words() -> None:
    with pytest.raises(ValueError, match="somersault"):
        pos_tag("a man does a somersault.")


def test_format_text_line_round_trips() -> None:
    caption = describe([act("kick", leg="left", count=2)], np.random.default_rng(1))[0]
    tags = pos_tag(caption)
    for start, end in ((0.0, 0.0), (1.5, 4.25)):
        line = format_text_line(caption, tags, start, end)
        text, tokens, f, t = line.split("#")
        assert text == caption and (float(f), float(t)) == (start, end)
        assert [tuple(tok.split("/")) for tok in tokens.split(" ")] == tags
    assert format_text_line("a man bows.", pos_tag("a man bows.")) == (
        "a man bows.#a/DET man/NOUN bow/VERB#0.0#0.0")
    with pytest.raises(ValueError):
        format_text_line("a # b", [])


KEYWORDS = {"kick": r"kick", "clap": r"clap", "bow": r"\bbow|waist", "jump": r"jump|leap"}


def first_mention(caption: str, family: str) -> int:
    match = re.search(KEYWORDS[family], caption)
    assert match, (family, caption)
    return match.start()


def test_before_and_after_keep_the_true_order() -> None:
    a, b = act("kick", leg="left", count=1), act("clap", count=3)
    seen = {"before": 0, "after": 0}
    for caption in captions_of([a, b], seeds=200):
        for word, later in (("before", "clap"), ("after", "kick")):
            clause = re.search(rf"\b{word} (?!that)([^,.]*)", caption)
            if clause:  # "before X" names the later action, "after X" the earlier one
                seen[word] += 1
                earlier = "kick" if later == "clap" else "clap"
                names = clause.group(1)
                assert re.search(KEYWORDS[later], names) and not re.search(KEYWORDS[earlier], names)
                break
        else:
            assert first_mention(caption, "kick") < first_mention(caption, "clap"), caption
    assert seen["before"] > 10 and seen["after"] > 10
    # Three actions are always told in their true order.
    three = [act("jump", mode="forward", count=2), act("clap", count=2), act("bow")]
    for caption in captions_of(three, seeds=100):
        assert first_mention(caption, "jump") < first_mention(caption, "clap") < first_mention(
            caption, "bow"), caption


def test_concurrent_action_is_said_with_while() -> None:
    walk, wave = act("walk", speed="normal", direction="forward"), act("wave", hand="left", count=2)
    turn = act("turn", side="right", angle=90)
    caps = captions_of([turn, walk], concurrent=wave)
    assert all(re.search(r"\bwhile\b|at the same time", c) and "wav" in c for c in caps)
    assert all(re.search(r"\bleft\b", c) for c in caps)  # the wave's side is always said
    assert canonical_label([turn, walk], concurrent=wave) == (
        "turn(angle=90,side=right) > "
        "walk(direction=forward,speed=normal) + wave(count=2,hand=left)")
    with pytest.raises(ValueError, match="locomotion"):
        describe([turn], np.random.default_rng(0), concurrent=wave)
    with pytest.raises(ValueError, match="kick"):
        describe([walk], np.random.default_rng(0), concurrent=act("kick", leg="left", count=1))
    with pytest.raises(ValueError, match="concurrent_with"):
        describe([turn, walk], np.random.default_rng(0), concurrent=wave, concurrent_with=0)


def test_canonical_label_and_bad_input() -> None:
    label = canonical_label([act("jump", mode="forward", count=np.int64(2), tempo=1.1), act("bow")])
    assert label == "jump(count=2,mode=forward) > bow"  # style params are not part of the label
    with pytest.raises(ValueError, match="somersault"):
        describe([act("somersault")], np.random.default_rng(0))
    with pytest.raises(ValueError, match="side"):
        describe([act("turn", side="up", angle=90)], np.random.default_rng(0))
    with pytest.raises(ValueError, match="count"):
        describe([act("squat")], np.random.default_rng(0))


def test_captions_cover_the_motion_vocabulary() -> None:
    """The motion side's families and values are all ones captions can state (guards drift)."""
    motion = pytest.importorskip("mlct.data.synth.actions")
    assert set(motion.FAMILIES) == set(FAMILIES)
    for family, spec in motion.FAMILY_PARAMS.items():
        required = set(ACTION_PARAMS[family]) - OPTIONAL_PARAMS.get(family, frozenset())
        assert required <= set(spec) <= set(ACTION_PARAMS[family]), family
        for key, values in spec.items():
            assert set(values) <= set(ACTION_PARAMS[family][key]), (family, key)
    assert set(motion.LOCOMOTION) <= LOCOMOTION and set(motion.UPPER_BODY) <= UPPER_BODY
    rng = np.random.default_rng(0)
    for _ in range(300):
        script = motion.sample_script(rng)
        for caption in describe(list(script.actions), rng, concurrent=script.concurrent):
            pos_tag(caption)
