"""Captions for procedural motions: HumanML3D-style paraphrases.

The language side of the synthetic benchmark. `describe` turns a sequence of actions (each with
`.family: str` and `.params: dict`) into distinct paraphrases such as "a man walks forward
quickly, then turns 90 degrees to the left."; mlct.data.captions tags them (`pos_tag`, whose
lexicon is this vocabulary) and stores them the way HumanML3D's texts/*.txt do. Captions are
always truthful: a phrase may leave a parameter out, but never states a wrong side, count,
angle, speed or order.
"""

from __future__ import annotations

import numbers
import re
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

from mlct.data.captions import VERB_FORMS
from mlct.data.synth.actions import FAMILY_PARAMS, VERSION_4_MODULES
from mlct.data.synth.phrases_more import BENCHMARK as MORE_PHRASES

# ---------------------------------------------------------------------------------------------
# The action spec, as captions see it. Only these keys are read; other params (style noise,
# tempo) are ignored, since no caption can state them.
# ---------------------------------------------------------------------------------------------

SIDES = ("left", "right")
SPEEDS = ("slow", "normal", "fast")
HANDS = ("left", "right", "both")

# Params a family may carry but need not (the motion side may add speed to any locomotion).
OPTIONAL_PARAMS: dict[str, frozenset[str]] = {
    f: frozenset({"speed"}) for f in ("jog", "run", "circle")
}
# One table of actions (actions.FAMILY_PARAMS), plus the optional params captions can state.
ACTION_PARAMS: dict[str, dict[str, tuple]] = {
    family: {**params, **({"speed": SPEEDS} if family in OPTIONAL_PARAMS else {})}
    for family, params in FAMILY_PARAMS.items()
}
FAMILIES: tuple[str, ...] = tuple(ACTION_PARAMS)
LOCOMOTION = frozenset({"walk", "jog", "run", "walk_backward", "circle"})
UPPER_BODY = frozenset({"wave", "raise_arms", "clap", "punch"})  # may run "while" walking


def _checked(action: Any) -> tuple[str, dict[str, Any]]:
    """(family, params restricted to the spec's keys), or ValueError naming what is wrong."""
    family = action.family
    if family not in ACTION_PARAMS:
        raise ValueError(f"unknown action family {family!r}; expected one of {', '.join(FAMILIES)}")
    params: dict[str, Any] = {}
    for key, allowed in ACTION_PARAMS[family].items():
        if key not in action.params:
            if key in OPTIONAL_PARAMS.get(family, ()):
                continue
            raise ValueError(f"action {family!r} lacks parameter {key!r}")
        value = action.params[key]
        # numpy scalars from the sampler (rng.choice gives np.str_ / np.int64) become plain.
        if isinstance(value, str):
            value = str(value)
        elif isinstance(value, numbers.Integral) and not isinstance(value, bool):
            value = int(value)
        if type(value) is not type(allowed[0]) or value not in allowed:  # True is not 1
            raise ValueError(f"action {family!r}: {key}={value!r} is not one of {allowed}")
        params[key] = value
    return family, params


# ---------------------------------------------------------------------------------------------
# Verbs. Templates mark each verb as <lemma>; rendering makes it "walks" or "walking"
# (the forms: mlct.data.captions.VERB_FORMS).
# ---------------------------------------------------------------------------------------------

_MARK = re.compile(r"<([a-z]+)>")


def _render(template: str, gerund: bool, forms: dict[str, tuple[str, str]] = VERB_FORMS) -> str:
    """Conjugate every <verb> in `template`: third person singular, or -ing when `gerund`."""
    return _MARK.sub(lambda m: forms[m.group(1)][gerund], template)


# ---------------------------------------------------------------------------------------------
# Phrases per family. Each returns one verb phrase with <verb> marks and HIS for the subject's
# possessive (his / her / their / the), chosen once per caption so pronouns agree.
# ---------------------------------------------------------------------------------------------

_NUM = ("zero", "one", "two", "three", "four", "five")
_ROTATION = {"left": "counterclockwise", "right": "clockwise"}  # seen from above, y up
_DEGREES = {
    45: ("45 degrees", "forty five degrees"),
    90: ("90 degrees", "ninety degrees"),
    135: ("135 degrees", "a hundred and thirty five degrees"),
    180: ("180 degrees", "a hundred and eighty degrees"),
}
_WALK_VERBS = {  # "stroll" implies an easy pace, "hurry" a quick one
    "slow": ("walk", "walk", "stroll"),
    "normal": ("walk", "walk", "pace", "move"),
    "fast": ("walk", "walk", "pace", "hurry"),
}
_WALK_SPEED = {
    "slow": ("slowly", "slowly", "at a slow pace", "at a leisurely pace"),
    "normal": ("", "", "", "at a normal pace", "at a steady pace"),
    "fast": ("quickly", "briskly", "fast", "rapidly", "at a fast pace", "at a brisk pace"),
}
_RUN_SPEED = {
    "slow": ("slowly", "at a slow pace"),
    "normal": ("",),
    "fast": ("quickly", "fast", "at a fast pace"),
}

Rng = np.random.Generator


def _pick(rng: Rng, options: Sequence[str]) -> str:
    return options[int(rng.integers(len(options)))]


def _num(n: int, rng: Rng) -> str:
    return _pick(rng, (_NUM[n], _NUM[n], str(n)))


def _times(n: int, rng: Rng) -> str:
    """A count adverb; a count of one may go unsaid, larger counts never do."""
    if n == 1:
        return _pick(rng, ("once", "", ""))
    return _pick(rng, ("twice", "twice", "two times", "2 times") if n == 2
                 else (f"{_NUM[n]} times", f"{n} times"))


def _n_of(n: int, singular: str, plural: str, rng: Rng) -> str:
    if n == 1:
        return _pick(rng, (f"a {singular}", f"a single {singular}", f"one {singular}"))
    return f"{_num(n, rng)} {plural}"


def _with_speed(phrase: str, speed: str, words: dict[str, tuple[str, ...]], rng: Rng) -> str:
    options = words[speed]
    if " at a " in phrase:  # "moves forward at a jog", so no second "at a ... pace"
        options = tuple(w for w in options if not w.startswith("at ")) or ("",)
    adverb = _pick(rng, options)
    if adverb.endswith("ly") and rng.random() < 0.5:
        return f"{adverb} {phrase}"  # "slowly walks forward"
    return f"{phrase} {adverb}"


def _hand(hand: str, rng: Rng, limb: str = "hand") -> str:
    if hand == "both":
        return _pick(rng, (f"both {limb}s", "both hands", "both arms", f"both HIS {limb}s"))
    return _pick(rng, (f"HIS {hand} {limb}", f"HIS {hand} {limb}", f"the {hand} hand"))


def _walk(p: dict, rng: Rng) -> str:
    way = _pick(rng, ("forward", "forward", "straight ahead", "ahead",
                      "forward in a straight line"))
    verb = _pick(rng, _WALK_VERBS[p["speed"]])
    words = _WALK_SPEED
    if verb == "pace":  # not "paces ahead at a steady pace"
        words = {k: tuple(w for w in ws if "pace" not in w) for k, ws in words.items()}
    return _with_speed(f"<{verb}> {way}", p["speed"], words, rng)


def _jog(p: dict, rng: Rng) -> str:
    speed = p.get("speed", "normal")
    steady = ("<jog> forward at a steady pace",) if speed == "normal" else ()
    phrase = _pick(rng, ("<jog> forward", "<jog> forward", "<jog> straight ahead", "<jog> ahead",
                         "<move> forward at a jog", "<jog> forward in a straight line") + steady)
    return _with_speed(phrase, speed, _RUN_SPEED, rng)


def _run(p: dict, rng: Rng) -> str:
    phrase = _pick(rng, ("<run> forward", "<run> forward", "<run> straight ahead", "<run> ahead",
                         "<dash> forward", "<run> forward in a straight line"))
    return _with_speed(phrase, p.get("speed", "normal"), _RUN_SPEED, rng)


def _walk_backward(p: dict, rng: Rng) -> str:
    phrase = _pick(rng, ("<walk> backward", "<walk> backwards", "<back> up", "<step> backward",
                         "<move> backwards", "<walk> in reverse"))
    return _with_speed(phrase, p["speed"], _WALK_SPEED, rng)


def _side_step(p: dict, rng: Rng) -> str:
    s, n = p["side"], p["steps"]
    return _pick(rng, (
        f"<take> {_num(n, rng)} steps to the {s}", f"<step> sideways to the {s} {_times(n, rng)}",
        f"<sidestep> to the {s} {_times(n, rng)}", f"<shuffle> {_num(n, rng)} steps to the {s}",
        f"<step> to the {s} {_times(n, rng)}", f"<move> {_num(n, rng)} steps sideways to HIS {s}",
    ))


def _turn(p: dict, rng: Rng) -> str:
    s, angle = p["side"], p["angle"]
    d = _pick(rng, _DEGREES[angle])
    general = (f"<turn> {d} to the {s}", f"<turn> {s} by {d}", f"<turn> {d} to HIS {s}",
               f"<rotate> {d} {_ROTATION[s]}", f"<pivot> {d} to the {s}")
    special = {  # everyday words, each true of that angle only
        45: (f"<turn> slightly to the {s}", f"<make> a slight {s} turn", f"<turn> slightly {s}"),
        90: (f"<turn> {s}", f"<turn> to the {s}", f"<make> a quarter turn to the {s}",
             f"<make> a {s} turn"),
        135: (f"<make> a sharp {s} turn", f"<turn> sharply to the {s}"),
        180: ("<turn> around", f"<turn> around to the {s}", f"<make> a half turn to the {s}",
              f"<turn> around over HIS {s} shoulder"),
    }[angle]
    return _pick(rng, general + special + special)  # everyday words twice as often


def _circle(p: dict, rng: Rng) -> str:
    s, rot = p["side"], _ROTATION[p["side"]]
    phrase = _pick(rng, (f"<walk> in a circle to the {s}", f"<walk> in a {rot} circle",
                         f"<walk> {rot} in a circle", f"<walk> around in a circle to the {s}",
                         f"<circle> around to the {s}", "<walk> in a circle"))
    return _with_speed(phrase, p.get("speed", "normal"), _WALK_SPEED, rng)


def _jump(p: dict, rng: Rng) -> str:
    n = p["count"]
    if p["mode"] == "in_place":
        # "up and down" suggests several jumps, so a single one never gets it.
        where = _pick(rng, ("in place", "on the spot", "up", "straight up")
                      + (("up and down",) if n > 1 else ()))
        return _pick(rng, (f"<jump> {where} {_times(n, rng)}", f"<jump> {_times(n, rng)} {where}",
                           f"<do> {_n_of(n, 'jump', 'jumps', rng)} in place"))
    where = _pick(rng, ("forward", "forward", "ahead"))
    return _pick(rng, (f"<jump> {where} {_times(n, rng)}", f"<leap> {where} {_times(n, rng)}",
                       f"<do> {_n_of(n, 'jump', 'jumps', rng)} forward"))


def _hop(p: dict, rng: Rng) -> str:
    s, n = p["leg"], p["count"]
    return _pick(rng, (
        f"<hop> on HIS {s} leg {_times(n, rng)}",
        f"<hop> on the {s} foot {_times(n, rng)}",
        f"<hop> {_times(n, rng)} on HIS {s} leg",
        f"<balance> on HIS {s} leg and <hop> {_times(n, rng)}",
        f"<do> {_n_of(n, 'hop', 'hops', rng)} on HIS {s} foot",
    ))


def _squat(p: dict, rng: Rng) -> str:
    n = p["count"]
    return _pick(rng, (
        f"<squat> {_times(n, rng)}",
        f"<squat> down {_times(n, rng)}",
        f"<do> {_n_of(n, 'squat', 'squats', rng)}",
        f"<squat> down and <stand> back up {_times(n, rng)}",
        f"<bend> HIS knees into a squat {_times(n, rng)}",
        f"<crouch> down {_times(n, rng)}",
    ))


def _sit_stand(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<sit> down on an invisible chair and <stand> back up",
                       "<sit> down and <get> back up",
                       "<sit> on an imaginary chair and <stand> up again",
                       "<sit> down briefly and <stand> up",
                       "<take> a seat on an invisible chair and <get> back up"))


def _wave(p: dict, rng: Rng) -> str:
    hand, t = _hand(p["hand"], rng), _times(p["count"], rng)
    return _pick(rng, (f"<wave> {hand} {t}", f"<wave> with {hand} {t}", f"<wave> {t} with {hand}",
                       f"<raise> {hand} and <wave> {t}", f"<wave> {hand} back and forth {t}"))


def _raise_arms(p: dict, rng: Rng) -> str:
    arm = _hand(p["hand"], rng, limb="arm")
    return _pick(rng, (f"<raise> {arm}", f"<raise> {arm} up", f"<lift> {arm} up",
                       f"<raise> {arm} above HIS head", f"<put> {arm} up in the air",
                       f"<raise> {arm} into the air", f"<lift> {arm} overhead"))


def _clap(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<clap> {t}", f"<clap> HIS hands {t}", f"<clap> HIS hands together {t}",
                       f"<clap> {t} in front of HIS chest"))


def _punch(p: dict, rng: Rng) -> str:
    s, n = p["hand"], p["count"]
    return _pick(rng, (
        f"<punch> with HIS {s} hand {_times(n, rng)}",
        f"<punch> forward with HIS {s} fist {_times(n, rng)}",
        f"<throw> {_n_of(n, f'{s} punch', f'{s} punches', rng)}",
        f"<throw> {_n_of(n, 'punch', 'punches', rng)} with HIS {s} hand",
        f"<jab> with HIS {s} arm {_times(n, rng)}",
    ))


def _kick(p: dict, rng: Rng) -> str:
    s, n = p["leg"], p["count"]
    return _pick(rng, (
        f"<kick> with HIS {s} leg {_times(n, rng)}",
        f"<kick> HIS {s} leg forward {_times(n, rng)}",
        f"<kick> {_times(n, rng)} with the {s} foot",
        f"<kick> out with HIS {s} foot {_times(n, rng)}",
        f"<do> {_n_of(n, f'{s} kick', f'{s} kicks', rng)}",
        f"<kick> forward with HIS {s} leg {_times(n, rng)}",
    ))


def _bow(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<bow>", "<bow> forward", "<take> a bow", "<bow> down", "<give> a deep bow",
                       "<bend> forward at the waist and <straighten> up", "<bow> politely"))


def _stretch(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<stretch> HIS arms overhead and <lean> to the side",
                       "<raise> HIS arms above HIS head and <bend> to one side",
                       "<stretch> HIS arms up and <bend> sideways",
                       "<reach> up high and <lean> to one side"))


def _spin(p: dict, rng: Rng) -> str:
    s, rot = p["side"], _ROTATION[p["side"]]
    return _pick(rng, (
        f"<spin> around to the {s}", f"<spin> in a full circle to the {s}",
        f"<do> a full spin to the {s}", f"<turn> a full circle to the {s}", f"<spin> {rot}",
        f"<turn> all the way around to the {s}", f"<turn> 360 degrees to the {s}",
        f"<turn> three hundred and sixty degrees {rot}", f"<make> a full turn to the {s}",
        f"<spin> around once {rot}",
    ))


def _kneel(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<kneel> on HIS {s} knee and <get> back up",
                       f"<kneel> down on the {s} knee and <stand> up again",
                       f"<go> down on HIS {s} knee and <rise> again",
                       f"<drop> to HIS {s} knee and <stand> back up"))


def _stand(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<stand> still", "<stand> in place", "<stay> still", "<stand> there",
                       "<stand> idle", "<wait> in place", "<stand> motionless",
                       "<stand> still for a moment", "<pause> for a moment", "<stand> quietly"))


_PHRASES: dict[str, Callable[[dict, Rng], str]] = {
    "walk": _walk, "jog": _jog, "run": _run, "walk_backward": _walk_backward,
    "side_step": _side_step, "turn": _turn, "circle": _circle, "jump": _jump, "hop": _hop,
    "squat": _squat, "sit_stand": _sit_stand, "wave": _wave, "raise_arms": _raise_arms,
    "clap": _clap, "punch": _punch, "kick": _kick, "bow": _bow, "stretch": _stretch,
    "spin": _spin, "kneel": _kneel, "stand": _stand,
    **MORE_PHRASES,  # the families of benchmark version 3
    **{f: phrase for m in VERSION_4_MODULES for f, phrase in m.PHRASES["benchmark"].items()},
}
assert set(_PHRASES) == set(FAMILIES)

# ---------------------------------------------------------------------------------------------
# Sentences: a subject, then the phrases joined in time order (or reordered by before/after).
# ---------------------------------------------------------------------------------------------

_SUBJECTS = (("a person", "their"), ("a person", "their"), ("the person", "their"),
             ("a man", "his"), ("the man", "his"), ("a woman", "her"), ("the woman", "her"),
             ("someone", "their"), ("a figure", "their"), ("the figure", "their"),
             ("a human", "their"))
_SPACES = re.compile(r"\s+")
_JOINS = (" then ", " and then ", " and ", ", then ", ", and then ", " and after that ",
          ", after that ")


def _concurrent_phrase(loco: str, upper: str, rng: Rng,
                       forms: dict[str, tuple[str, str]] = VERB_FORMS) -> str:
    """One phrase for two simultaneous actions; the upper-body one is said with 'while'."""
    kind = int(rng.integers(4))
    if kind <= 1:
        return f"{loco} while {_render(upper, True, forms)}"
    if kind == 2:
        return f"{upper} while {_render(loco, True, forms)}"
    return f"{loco} and {upper} at the same time"


def _sentence(subject: str, phrases: list[str], rng: Rng,
              forms: dict[str, tuple[str, str]] = VERB_FORMS) -> str:
    """Join phrases (already in time order) into one sentence about `subject`."""
    fin = [_render(p, False, forms) for p in phrases]
    ing = [_render(p, True, forms) for p in phrases]
    if len(phrases) == 1:
        return f"{subject} is {ing[0]}" if rng.random() < 0.15 else f"{subject} {fin[0]}"
    forms = ["chain"] * 5 + ["first", "progressive", "before", "after_first"]
    if len(phrases) == 2:  # with three, these would leave the middle action's place unclear
        forms += ["before_first", "after"]
    form = _pick(rng, forms)
    if form == "progressive":  # "a man is walking forward and then turning left"
        return f"{subject} is " + _chain(ing, rng)
    if form == "first":  # "a man first walks forward, then turns left(, and finally ...)"
        tail = "".join(f", and finally {p}" for p in fin[2:])
        return f"{subject} first {fin[0]}, then {fin[1]}{tail}"
    if form == "before":  # "a man walks forward before turning left": order kept
        return f"{subject} " + _chain(fin[:-1], rng) + f" before {ing[-1]}"
    if form == "after_first":  # "after walking forward, a man turns left": order kept
        return f"after {ing[0]}, {subject} " + _chain(fin[1:], rng)
    if form == "before_first":  # "before turning left, a man walks forward": reversed in text
        return f"before {ing[1]}, {subject} {fin[0]}"
    if form == "after":  # "a man turns left after walking forward": reversed in text
        return f"{subject} {fin[1]} after {ing[0]}"
    return f"{subject} " + _chain(fin, rng)


class Vocabulary(NamedTuple):
    """What a caption is made of: a phrase maker per family, (subject, possessive) pairs, and the
    forms (third person, gerund) of every <verb> the phrases mark."""

    phrases: dict[str, Callable[[dict, Rng], str]]
    subjects: tuple[tuple[str, str], ...]
    forms: dict[str, tuple[str, str]]


BENCHMARK = Vocabulary(_PHRASES, _SUBJECTS, VERB_FORMS)


def _chain(parts: list[str], rng: Rng) -> str:
    """Phrases in order; a list of three may open with a bare comma ("walks, turns and ...")."""
    out = parts[0]
    for i, part in enumerate(parts[1:], start=1):
        first_of_three = len(parts) == 3 and i == 1
        out += _pick(rng, _JOINS + ((", ",) if first_of_three else ())) + part
    return out


def _concurrent_index(families: list[str], concurrent: Any, concurrent_with: int | None) -> int:
    """Which action the concurrent one accompanies: the given index, else the first locomotion."""
    family, _ = _checked(concurrent)
    if family not in UPPER_BODY:
        raise ValueError(f"{family!r} cannot be done while walking; "
                         f"use one of {sorted(UPPER_BODY)}")
    if concurrent_with is None:
        at = next((i for i, f in enumerate(families) if f in LOCOMOTION), None)
        if at is None:
            raise ValueError(f"concurrent {family!r} needs a locomotion action, got {families}")
        return at
    if not 0 <= concurrent_with < len(families) or families[concurrent_with] not in LOCOMOTION:
        raise ValueError(f"concurrent_with={concurrent_with} is not a locomotion action "
                         f"of {families}")
    return concurrent_with


def describe(actions: Sequence[Any], rng: Rng, n_captions: int = 3, concurrent: Any = None,
             concurrent_with: int | None = None, vocabulary: Vocabulary | None = None
             ) -> list[str]:
    """`n_captions` distinct truthful captions of `actions` (in time order); `concurrent` is an
    upper-body action done while `actions[concurrent_with]` (default: the first locomotion).
    vocabulary: phrases, subjects and verb forms (default: the benchmark's own, BENCHMARK)."""
    phrase_of, subjects, forms = vocabulary or BENCHMARK
    if not actions:
        raise ValueError("describe needs at least one action")
    checked = [_checked(a) for a in actions]
    at = -1 if concurrent is None else _concurrent_index([f for f, _ in checked], concurrent,
                                                         concurrent_with)
    with_ = None if concurrent is None else _checked(concurrent)
    captions: list[str] = []
    for _ in range(50 * n_captions):  # templates x subjects give hundreds of variants; retry dups
        subject, possessive = _pick(rng, subjects)
        if rng.random() < 0.25:
            possessive = "the"  # "kicks with the left leg"
        phrases = [phrase_of[f](p, rng) for f, p in checked]
        if with_ is not None:
            upper = phrase_of[with_[0]](with_[1], rng)
            phrases[at] = _concurrent_phrase(phrases[at], upper, rng, forms)
        text = _sentence(subject, phrases, rng, forms).replace("HIS", possessive)
        text = _SPACES.sub(" ", text).replace(" ,", ",").strip() + "."
        if text not in captions:
            captions.append(text)
            if len(captions) == n_captions:
                return captions
    raise ValueError(f"could not find {n_captions} distinct captions for {checked}")


def canonical_label(actions: Sequence[Any], concurrent: Any = None,
                    concurrent_with: int | None = None) -> str:
    """Short exact label of what captions can state, e.g.
    'walk(direction=forward,speed=fast) + wave(count=2,hand=right) > turn(angle=90,side=left)'."""

    def one(action: Any) -> str:
        family, params = _checked(action)
        args = ",".join(f"{k}={v}" for k, v in sorted(params.items()))
        return f"{family}({args})" if args else family

    parts = [one(a) for a in actions]
    if concurrent is not None:
        at = _concurrent_index([_checked(a)[0] for a in actions], concurrent, concurrent_with)
        parts[at] += " + " + one(concurrent)
    return " > ".join(parts)
