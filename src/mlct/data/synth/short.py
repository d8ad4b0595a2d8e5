"""Short captions for procedural motions: each action named by its bare verb.

People type "a woman walks", "a person waves", "someone stretches". The benchmark's templates
(text.py) always spell out what they can: which hand, how far, how many, "stretches their arms
overhead and leans to the side", and so do the everyday phrases (everyday.py). No training
caption was a bare verb, and the bundled model made these prompts badly: "a person waves" gave
a kick, "a woman walks" stood still, "a woman stretches" held the arms at the chest (docs/
training.md, "Short prompts"). This vocabulary says each action as briefly as people do,
leaving parameters out but never stating a wrong one (a left-handed wave is "waves", "waves a
hand"; a wave with both hands is never "waves a hand"). Its verbs are the benchmark's own
(VERB_FORMS), so the held-out paraphrases of bench/data stay unseen wording.

`mlct data rephrase SRC --vocabulary short` adds captions made with it to a training split.
"""

from __future__ import annotations

from collections.abc import Callable

from mlct.data.captions import VERB_FORMS
from mlct.data.synth.everyday import SUBJECTS as EVERYDAY_SUBJECTS
from mlct.data.synth.text import _SUBJECTS, FAMILIES, Rng, Vocabulary, _pick


def _one_or_both(hand: str, one: tuple[str, ...], both: tuple[str, ...], rng: Rng) -> str:
    return _pick(rng, both if hand == "both" else one)


_FIXED: dict[str, tuple[str, ...]] = {
    "walk": ("<walk>", "<walk>", "<go> for a walk", "<take> a walk"),
    "jog": ("<jog>", "<jog>", "<go> for a jog"),
    "run": ("<run>", "<run>", "<go> for a run"),
    "walk_backward": ("<walk> backward", "<walk> backwards", "<step> back"),
    "side_step": ("<step> sideways", "<step> to the side", "<sidestep>"),
    "turn": ("<turn>", "<turn>", "<turn> to the side"),
    "circle": ("<walk> in a circle", "<walk> around in a circle", "<circle> around"),
    "hop": ("<hop>", "<hop>", "<hop> on one foot", "<hop> on one leg"),
    "squat": ("<squat>", "<squat>", "<squat> down"),
    "sit_stand": ("<sit> down and <stand> up", "<sit> down, then <get> up", "<sit> and <stand>"),
    "kneel": ("<kneel>", "<kneel>", "<kneel> down"),
    "clap": ("<clap>", "<clap>", "<clap> HIS hands"),
    "punch": ("<punch>", "<punch>", "<throw> punches"),
    "kick": ("<kick>", "<kick>", "<kick> out"),
    "bow": ("<bow>", "<bow>", "<bow> down"),
    "stretch": ("<stretch>", "<stretch>", "<stretch> out"),
    "spin": ("<spin>", "<spin>", "<spin> around"),
    "stand": ("<stand> still", "<stand> there", "<stand> in place", "<stay> still"),
}


def _fixed(family: str) -> Callable[[dict, Rng], str]:
    return lambda p, rng: _pick(rng, _FIXED[family])


def _jump(p: dict, rng: Rng) -> str:
    if p["mode"] == "forward":
        return _pick(rng, ("<jump>", "<jump> forward"))
    return _pick(rng, ("<jump>", "<jump>", "<jump> up"))


def _wave(p: dict, rng: Rng) -> str:
    return _one_or_both(p["hand"], ("<wave>", "<wave>", "<wave> a hand"),
                        ("<wave>", "<wave> both hands"), rng)


def _raise_arms(p: dict, rng: Rng) -> str:
    return _one_or_both(p["hand"], ("<raise> an arm", "<raise> a hand", "<put> a hand up"),
                        ("<raise> HIS arms", "<raise> both arms", "<put> HIS hands up"), rng)


PHRASES: dict[str, Callable[[dict, Rng], str]] = {
    **{family: _fixed(family) for family in _FIXED},
    "jump": _jump, "wave": _wave, "raise_arms": _raise_arms,
}
assert set(PHRASES) == set(FAMILIES)

SHORT = Vocabulary(PHRASES, tuple(dict.fromkeys(_SUBJECTS + EVERYDAY_SUBJECTS)), VERB_FORMS)
