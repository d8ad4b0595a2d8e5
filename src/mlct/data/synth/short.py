"""Short captions for procedural motions: each action named by its bare verb.

People type "a woman walks", "a person waves", "someone stretches". The benchmark's templates
(text.py) always spell out what they can: which hand, how far, how many, "stretches their arms
overhead and leans to the side", and so do the everyday phrases (everyday.py). No training
caption was a bare verb, and the bundled model made these prompts badly: "a person waves" gave
a kick, "a woman walks" stood still, "a woman stretches" held the arms at the chest (`bench/quality.py
short`; docs/training.md). This vocabulary says each action as briefly as people do,
leaving parameters out but never stating a wrong one. A bare verb of a one-sided action means
its right-sided form ("a person kicks": the right leg; the left one keeps the benchmark's
words, which name it); a direction is said ("turns left"). Its verbs are the benchmark's own
(VERB_FORMS), so the held-out paraphrases of bench/data stay unseen wording.

`mlct data rephrase SRC --vocabulary short` adds captions made with it to a training split.
"""

from __future__ import annotations

from collections.abc import Callable

from mlct.data.captions import VERB_FORMS
from mlct.data.synth.actions import VERSION_4_MODULES
from mlct.data.synth.everyday import ALL_SUBJECTS
from mlct.data.synth.phrases_more import SHORT as MORE_PHRASES
from mlct.data.synth.text import BENCHMARK, FAMILIES, Rng, Vocabulary, _pick, _times


_FIXED: dict[str, tuple[str, ...]] = {
    "walk": ("<walk>", "<walk>", "<go> for a walk", "<take> a walk"),
    "jog": ("<jog>", "<jog>", "<go> for a jog"),
    "run": ("<run>", "<run>", "<go> for a run"),
    "walk_backward": ("<walk> backward", "<walk> backwards", "<step> back"),
    "squat": ("<squat>", "<squat>", "<squat> down"),
    "sit_stand": ("<sit> down and <stand> up", "<sit> down, then <get> up", "<sit> and <stand>"),
    "clap": ("<clap>", "<clap>", "<clap> HIS hands"),
    "bow": ("<bow>", "<bow>", "<bow> down"),
    "stretch": ("<stretch>", "<stretch>", "<stretch> out"),
    "stand": ("<stand> still", "<stand> there", "<stand> in place", "<stay> still"),
}
# A bare verb of a one-sided action means the right hand or foot, as for most people: the
# phrase is said of right-sided motions only. Said of both sides, it was a blend of the two to
# the model: 6,000 steps on it made "a person kicks" a half-kick of either leg (plain samples
# 16/16 -> 11/16 pass), bench/quality.py short.
_RIGHT_SIDED: dict[str, tuple[str, ...]] = {
    "hop": ("<hop>", "<hop>", "<hop> on one foot", "<hop> on one leg"),
    "kneel": ("<kneel>", "<kneel>", "<kneel> down"),
    "punch": ("<punch>", "<punch>", "<throw> punches"),
    "kick": ("<kick>", "<kick>", "<kick> out"),
    "wave": ("<wave>", "<wave>", "<wave> a hand"),
    "raise_arms": ("<raise> an arm", "<raise> a hand", "<put> a hand up"),
}
_SIDE_KEY = {"hop": "leg", "kneel": "leg", "kick": "leg", "punch": "hand", "wave": "hand",
             "raise_arms": "hand"}
_BOTH_HANDS = {"wave": ("<wave> both hands", "<wave> both arms"),
               "raise_arms": ("<raise> HIS arms", "<raise> both arms", "<put> HIS hands up")}


def _fixed(family: str) -> Callable[[dict, Rng], str]:
    return lambda p, rng: _pick(rng, _FIXED[family])


def _sided(family: str) -> Callable[[dict, Rng], str]:
    """The bare phrase for the right side, both hands said as both, the left side in the
    benchmark's own words (which name it)."""
    def phrase(p: dict, rng: Rng) -> str:
        side = p[_SIDE_KEY[family]]
        if side == "right":
            return _pick(rng, _RIGHT_SIDED[family])
        if side == "both":
            return _pick(rng, _BOTH_HANDS[family])
        return BENCHMARK.phrases[family](p, rng)
    return phrase


# A bare "jumps" means jumping in place, as a bare "kicks" means the right leg; a forward jump
# keeps the benchmark's words, which say "forward". Said of both (version 4 of the recipe and
# before), it was a blend to the model: "a person jumps twice" landed over 0.5 m ahead in 4 seeds
# of 5 (bench/quality.py examples). The count may be said: "jumps twice" is still short.
def _jump(p: dict, rng: Rng) -> str:
    if p["mode"] == "forward":
        return BENCHMARK.phrases["jump"](p, rng)
    return _pick(rng, ("<jump>", "<jump>", "<jump> up", f"<jump> {_times(p['count'], rng)}"))


# A direction is not a handedness: a turn, spin, circle or side step is said short, with its
# side. A turn said without its size is a quarter turn, as in the benchmark's captions; other
# sizes keep the benchmark's words, which name them. Said of every size (version 4 and before),
# "a person turns left" became a 40-180 degree blend the critic cut to 40-60 degrees in 3 seeds
# of 5 (bench/quality.py turns).
def _turn(p: dict, rng: Rng) -> str:
    if p["angle"] != 90:
        return BENCHMARK.phrases["turn"](p, rng)
    return _pick(rng, (f"<turn> {p['side']}", f"<turn> to the {p['side']}"))


def _spin(p: dict, rng: Rng) -> str:
    return _pick(rng, (f"<spin> {p['side']}", f"<spin> around to the {p['side']}"))


def _circle(p: dict, rng: Rng) -> str:
    return _pick(rng, (f"<walk> in a circle to the {p['side']}", f"<circle> {p['side']}"))


def _side_step(p: dict, rng: Rng) -> str:
    return _pick(rng, (f"<step> to the {p['side']}", f"<step> sideways to the {p['side']}"))


PHRASES: dict[str, Callable[[dict, Rng], str]] = {
    **{family: _fixed(family) for family in _FIXED},
    **{family: _sided(family) for family in _RIGHT_SIDED},
    "jump": _jump, "turn": _turn, "spin": _spin, "circle": _circle, "side_step": _side_step,
    **MORE_PHRASES,  # the families of benchmark version 3
    **{f: phrase for m in VERSION_4_MODULES for f, phrase in m.PHRASES["short"].items()},
}
assert set(PHRASES) == set(FAMILIES)

SHORT = Vocabulary(PHRASES, ALL_SUBJECTS, VERB_FORMS)
