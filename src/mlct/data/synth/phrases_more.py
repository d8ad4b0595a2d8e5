"""Phrases of the families benchmark version 3 adds, in each vocabulary: the benchmark's own
(text.py), everyday, colloquial and short (each of those modules takes its entries from here).

The rules are those of each vocabulary: a side is always said in the benchmark's words (the
short vocabulary falls back on them for the left side) and never the other side, not even of
the idle limb; a count is always said (short: never); "both" hands are said as both. <verb>
marks and HIS as in text.py. Only helpers with no state are taken from text.py, so this module
can be imported while text.py is being loaded.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Rng = np.random.Generator
Phrase = Callable[[dict, Rng], str]
_NUM = ("zero", "one", "two", "three", "four", "five")


def _pick(rng: Rng, options: tuple[str, ...]) -> str:
    return options[int(rng.integers(len(options)))]


def _count(n: int, rng: Rng) -> str:
    return _pick(rng, (_NUM[n], _NUM[n], str(n)))


def _times(n: int, rng: Rng) -> str:
    return _pick(rng, ("twice", "two times") if n == 2 else (f"{_NUM[n]} times", f"{n} times"))


def _hands(hand: str, rng: Rng) -> str:
    if hand == "both":
        return _pick(rng, ("both hands", "both HIS hands", "both of HIS hands"))
    return _pick(rng, (f"HIS {hand} hand", f"the {hand} hand"))


def _table(**phrases: tuple[str, ...]) -> dict[str, Phrase]:
    """Families whose phrases state no parameter: a fixed choice each."""
    return {family: (lambda options: lambda p, rng: _pick(rng, options))(options)
            for family, options in phrases.items()}


# ---------------------------------------------------------------------------- benchmark

def _pick_up(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<pick> something up from the floor with {h}",
                       f"<bend> down and <pick> up an object with {h}",
                       f"<reach> down to the floor with {h} and <pick> something up",
                       f"<squat> down and <pick> something up with {h}",
                       f"<pick> up an object from the ground with {h}"))


def _jumping_jack(p: dict, rng: Rng) -> str:
    n = p["count"]
    return _pick(rng, (f"<do> {_count(n, rng)} jumping jacks",
                       f"<perform> {_count(n, rng)} jumping jacks",
                       f"<jump> into {_count(n, rng)} jumping jacks"))


def _one_leg_stand(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<stand> on HIS {s} leg", f"<balance> on HIS {s} leg",
                       f"<stand> on the {s} foot with the other knee raised",
                       f"<balance> on the {s} foot for a moment",
                       f"<lift> one foot and <balance> on HIS {s} leg"))


def _point(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<point> forward with {h}", f"<point> straight ahead with {h}",
                       f"<point> at something in front with {h}",
                       f"<raise> {h} and <point> forward"))


def _salute(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<salute> with {h}", f"<give> a salute with {h}",
                       f"<raise> {h} to HIS forehead in a salute"))


def _push_up(p: dict, rng: Rng) -> str:
    n = _count(p["count"], rng)
    return _pick(rng, (f"<do> {n} pushups", f"<perform> {n} pushups",
                       f"<get> down on the floor and <do> {n} pushups",
                       f"<drop> down and <do> {n} pushups"))


def _lunge(p: dict, rng: Rng) -> str:
    s, n = p["leg"], p["count"]
    return _pick(rng, (f"<do> {_count(n, rng)} lunges with HIS {s} leg",
                       f"<lunge> forward with the {s} leg {_times(n, rng)}",
                       f"<step> forward into a lunge with HIS {s} leg {_times(n, rng)}",
                       f"<do> {_count(n, rng)} forward lunges on the {s} leg"))


def _nod(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<nod> {t}", f"<nod> HIS head {t}", f"<nod> HIS head forward {t}"))


BENCHMARK: dict[str, Phrase] = {
    **_table(
        lie_down=("<lie> down on HIS back", "<lie> down on the floor", "<lie> down",
                  "<lie> down flat on HIS back", "<get> down and <lie> on the floor",
                  "<sit> down and <lie> back on the floor"),
        get_up=("<get> up from the floor", "<stand> up from lying on HIS back",
                "<get> up off the floor", "<rise> from the floor to standing",
                "<get> up from lying down"),
        sit_floor=("<sit> down on the floor", "<sit> down on the ground",
                   "<sit> on the floor with HIS legs out", "<take> a seat on the floor",
                   "<sit> down on the floor and <lean> back on HIS hands"),
        touch_toes=("<touch> HIS toes", "<bend> over and <touch> HIS toes",
                    "<reach> down and <touch> HIS toes", "<reach> down to HIS toes",
                    "<touch> HIS toes with straight legs"),
        hands_on_hips=("<put> HIS hands on HIS hips", "<stand> with HIS hands on HIS hips",
                       "<place> both hands on HIS hips", "<rest> HIS hands on HIS hips"),
        cross_arms=("<cross> HIS arms", "<fold> HIS arms across HIS chest",
                    "<cross> HIS arms in front of HIS chest", "<stand> with HIS arms crossed"),
        march_in_place=("<march> in place", "<march> on the spot",
                        "<march> in place with high knees",
                        "<step> in place, lifting HIS knees high"),
    ),
    "pick_up": _pick_up, "jumping_jack": _jumping_jack, "one_leg_stand": _one_leg_stand,
    "point": _point, "salute": _salute, "nod": _nod, "push_up": _push_up, "lunge": _lunge,
}


# ---------------------------------------------------------------------------- everyday

def _e_pick_up(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<crouch> and <grab> something off the floor with {h}",
                       f"<bring> something up from the ground, using {h}",
                       f"<lower> down, <take> hold of something with {h} and <come> back up"))


def _e_jumping_jack(p: dict, rng: Rng) -> str:
    n = _count(p["count"], rng)
    return _pick(rng, (f"<warm> up with {n} jumping jacks", f"<bounce> through {n} jumping jacks",
                       f"<do> {n} star jumps"))


def _e_one_leg_stand(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<hold> HIS balance on the {s} leg", f"<keep> steady on just the {s} foot",
                       f"<stay> up on HIS {s} leg alone"))


def _e_point(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<signal> ahead by pointing with {h}", f"<hold> out {h}, pointing ahead",
                       f"<stick> out {h} to point at something"))


def _e_salute(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<bring> {h} up to the brow in a salute", f"<give> a crisp salute with {h}",
                       f"<snap> {h} to HIS brow"))


def _e_push_up(p: dict, rng: Rng) -> str:
    n = _count(p["count"], rng)
    return _pick(rng, (f"<lower> to the floor for {n} pushups", f"<warm> up with {n} pushups",
                       f"<push> up off the floor {_times(p['count'], rng)} from a plank"))


def _e_lunge(p: dict, rng: Rng) -> str:
    s, n = p["leg"], p["count"]
    return _pick(rng, (f"<sink> into {_count(n, rng)} lunges, the {s} foot in front",
                       f"<stride> out onto the {s} foot and <sink> low, {_times(n, rng)}"))


def _e_nod(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<tilt> HIS head forward {t}", f"<bob> HIS head {t}",
                       f"<say> yes with a nod, {t}"))


EVERYDAY: dict[str, Phrase] = {
    **_table(
        lie_down=("<settle> down onto HIS back", "<stretch> out flat on the floor",
                  "<lower> HIS body down until lying on the ground"),
        get_up=("<come> up off the ground", "<push> up off the floor and <stand>",
                "<rise> from the ground back to HIS feet"),
        sit_floor=("<settle> down on the ground", "<lower> down to sit on the floor",
                   "<sink> down to a seat on the ground"),
        touch_toes=("<fold> forward and <reach> for HIS toes", "<stretch> down toward HIS feet",
                    "<lean> all the way down to HIS toes"),
        hands_on_hips=("<keep> HIS hands on HIS hips", "<plant> HIS hands on HIS hips",
                       "<hold> HIS hands at HIS waist, elbows out"),
        cross_arms=("<keep> HIS arms folded", "<hold> HIS arms folded across HIS chest",
                    "<wrap> HIS arms across HIS chest"),
        march_in_place=("<march> without going anywhere", "<stomp> in place, knees up",
                        "<march> on the same spot"),
    ),
    "pick_up": _e_pick_up, "jumping_jack": _e_jumping_jack, "one_leg_stand": _e_one_leg_stand,
    "point": _e_point, "salute": _e_salute, "nod": _e_nod, "push_up": _e_push_up,
    "lunge": _e_lunge,
}
# The verbs these everyday phrases add to the benchmark's and everyday.py's own.
EVERYDAY_VERBS = {"grab": ("grabs", "grabbing"), "push": ("pushes", "pushing"),
                  "snap": ("snaps", "snapping"), "bob": ("bobs", "bobbing"),
                  "wrap": ("wraps", "wrapping"), "stomp": ("stomps", "stomping")}


# ---------------------------------------------------------------------------- colloquial

def _c_pick_up(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<scoop> something up off the floor with {h}",
                       f"<hunker> down and <grab> an item with {h}"))


def _c_jumping_jack(p: dict, rng: Rng) -> str:
    n = _count(p["count"], rng)
    return _pick(rng, (f"<knock> out {n} jumping jacks", f"<bang> out {n} star jumps"))


def _c_one_leg_stand(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<stand> like a flamingo on the {s} leg", f"<perch> on HIS {s} foot"))


def _c_point(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<jab> a finger ahead with {h}", f"<gesture> forward, pointing with {h}"))


def _c_salute(p: dict, rng: Rng) -> str:
    h = _hands(p["hand"], rng)
    return _pick(rng, (f"<snap> off a salute with {h}", f"<throw> a salute with {h}"))


def _c_push_up(p: dict, rng: Rng) -> str:
    n = _count(p["count"], rng)
    return _pick(rng, (f"<knock> out {n} pushups", f"<bang> out {n} press-ups"))


def _c_lunge(p: dict, rng: Rng) -> str:
    s, n = p["leg"], p["count"]
    return _pick(rng, (f"<knock> out {_count(n, rng)} lunges on the {s} leg",
                       f"<dip> into a lunge on HIS {s} leg {_times(n, rng)}"))


def _c_nod(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<bob> HIS head {t}", f"<dip> HIS chin {t}"))


COLLOQUIAL: dict[str, Phrase] = {
    **_table(
        lie_down=("<flop> down on HIS back", "<stretch> out flat on the deck"),
        get_up=("<haul> HIS body up off the floor", "<clamber> back up onto HIS feet"),
        sit_floor=("<plop> down on the floor", "<plonk> down on the ground"),
        touch_toes=("<fold> in half to touch HIS toes", "<limber> up by touching HIS toes"),
        hands_on_hips=("<stand> arms akimbo", "<prop> HIS hands on HIS hips"),
        cross_arms=("<fold> HIS arms, waiting", "<stand> with HIS arms folded tight"),
        march_in_place=("<stomp> on the spot like a soldier", "<march> in place, knees high"),
    ),
    "pick_up": _c_pick_up, "jumping_jack": _c_jumping_jack, "one_leg_stand": _c_one_leg_stand,
    "point": _c_point, "salute": _c_salute, "nod": _c_nod, "push_up": _c_push_up,
    "lunge": _c_lunge,
}
COLLOQUIAL_VERBS = {"scoop": ("scoops", "scooping"), "knock": ("knocks", "knocking"),
                    "bang": ("bangs", "banging"), "gesture": ("gestures", "gesturing"),
                    "dip": ("dips", "dipping"), "flop": ("flops", "flopping"),
                    "haul": ("hauls", "hauling"), "clamber": ("clambers", "clambering"),
                    "plop": ("plops", "plopping"), "plonk": ("plonks", "plonking"),
                    "prop": ("props", "propping")}


# ---------------------------------------------------------------------------- short

def _s_sided(family: str, key: str, bare: tuple[str, ...],
             both: tuple[str, ...] = ()) -> Phrase:
    """The bare phrase for the right side (as short.py's one-sided actions), the benchmark's
    words, which name it, for the left; both hands said as both."""
    def phrase(p: dict, rng: Rng) -> str:
        if p[key] == "left":
            return BENCHMARK[family](p, rng)
        return _pick(rng, both if p[key] == "both" else bare)
    return phrase


SHORT: dict[str, Phrase] = {
    **_table(
        lie_down=("<lie> down", "<lie> down", "<lie> on the floor"),
        get_up=("<get> up", "<get> up", "<stand> up from the floor"),
        sit_floor=("<sit> on the floor", "<sit> on the floor", "<sit> on the ground"),
        touch_toes=("<touch> HIS toes", "<touch> HIS toes"),
        hands_on_hips=("<stand> hands on hips", "<put> HIS hands on hips"),
        cross_arms=("<cross> HIS arms", "<cross> HIS arms", "<fold> HIS arms"),
        march_in_place=("<march> in place", "<march>"),
        jumping_jack=("<do> jumping jacks", "<do> jumping jacks"),
        nod=("<nod>", "<nod>", "<nod> HIS head"),
        push_up=("<do> pushups", "<do> pushups"),
    ),
    "pick_up": _s_sided("pick_up", "hand", ("<pick> something up", "<pick> something up"),
                        both=("<lift> something with both hands",)),
    "one_leg_stand": _s_sided("one_leg_stand", "leg", ("<stand> on one leg",
                                                       "<balance> on one leg")),
    "point": _s_sided("point", "hand", ("<point>", "<point>", "<point> forward")),
    "salute": _s_sided("salute", "hand", ("<salute>", "<salute>")),
    "lunge": _s_sided("lunge", "leg", ("<lunge>", "<do> lunges", "<lunge> forward")),
}
