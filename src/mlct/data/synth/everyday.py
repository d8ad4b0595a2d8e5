"""Everyday captions for procedural motions: a second vocabulary beside the benchmark's.

The benchmark's captions (text.py) come from a few templates per family, so a model trained on
them learns those words: "someone trots forward" or "a person applauds" was far from every
caption it saw, and it passed 0.42 of the hand-written paraphrases' read-out checks against
0.84 for one-action test captions (docs/training.md). This vocabulary says the same actions the
way people do (other verbs, idioms, subjects), equally truthful: a phrase may leave a parameter
out but never states a wrong side, count, angle, speed or order. `mlct data rephrase` adds
captions made with it to a benchmark's training split (data/synth/rephrase.py); the benchmark
itself, its test split and its version do not change.

It was written after the 42 paraphrases of bench/data/quality_prompts.json, so those no longer
measure unseen wording; bench/data/quality_prompts_heldout.json does (tests/test_everyday.py
checks that its prompts use none of the verbs this vocabulary adds).
"""

from __future__ import annotations

from collections.abc import Callable

from mlct.data.captions import VERB_FORMS
from mlct.data.synth.actions import VERSION_4_MODULES
from mlct.data.synth.phrases_more import EVERYDAY as MORE_PHRASES
from mlct.data.synth.phrases_more import EVERYDAY_VERBS as MORE_VERBS
from mlct.data.synth.text import (_DEGREES, _ROTATION, _SUBJECTS, FAMILIES, Rng, Vocabulary,
                                  _hand, _n_of,
                                  _num, _pick, _times)

# Verbs this vocabulary adds to the benchmark's, with (third person, gerund).
_NEW_VERBS = {
    "amble": ("ambles", "ambling"), "wander": ("wanders", "wandering"),
    "head": ("heads", "heading"), "advance": ("advances", "advancing"),
    "march": ("marches", "marching"), "stride": ("strides", "striding"),
    "trot": ("trots", "trotting"), "sprint": ("sprints", "sprinting"),
    "race": ("races", "racing"), "rush": ("rushes", "rushing"), "retreat": ("retreats", "retreating"),
    "slide": ("slides", "sliding"), "swivel": ("swivels", "swivelling"),
    "face": ("faces", "facing"), "twist": ("twists", "twisting"), "loop": ("loops", "looping"),
    "spring": ("springs", "springing"), "bound": ("bounds", "bounding"),
    "bounce": ("bounces", "bouncing"), "lower": ("lowers", "lowering"),
    "come": ("comes", "coming"), "greet": ("greets", "greeting"), "say": ("says", "saying"),
    "signal": ("signals", "signalling"), "hold": ("holds", "holding"),
    "stick": ("sticks", "sticking"), "applaud": ("applauds", "applauding"),
    "slap": ("slaps", "slapping"), "bring": ("brings", "bringing"), "strike": ("strikes", "striking"),
    "hit": ("hits", "hitting"), "boot": ("boots", "booting"), "swing": ("swings", "swinging"),
    "loosen": ("loosens", "loosening"), "warm": ("warms", "warming"), "tilt": ("tilts", "tilting"),
    "twirl": ("twirls", "twirling"), "whirl": ("whirls", "whirling"), "remain": ("remains", "remaining"),
    "keep": ("keeps", "keeping"), "fire": ("fires", "firing"), "sink": ("sinks", "sinking"),
    "plant": ("plants", "planting"), "lunge": ("lunges", "lunging"), "settle": ("settles", "settling"),
}
_NEW_VERBS.update(MORE_VERBS)
for _module in VERSION_4_MODULES:
    _NEW_VERBS.update(_module.VERBS["everyday"])
EVERYDAY_VERBS = frozenset(_NEW_VERBS)
FORMS: dict[str, tuple[str, str]] = {**VERB_FORMS, **_NEW_VERBS}


def _speed_word(speed: str, rng: Rng) -> str:
    return _pick(rng, {"slow": ("slowly", "at an easy pace", "without hurrying", "gently"),
                       "normal": ("", "", "at an ordinary pace", "at walking pace"),
                       "fast": ("quickly", "in a hurry", "with long quick steps", "at speed")}[speed])


def _walk(p: dict, rng: Rng) -> str:
    verb = _pick(rng, {"slow": ("amble", "wander", "stroll", "walk"),
                       "normal": ("head", "advance", "walk", "go"),
                       "fast": ("march", "stride", "hurry", "walk")}[p["speed"]])
    way = _pick(rng, ("forward", "ahead", "onward", "straight ahead", "forward on foot"))
    return f"<{verb}> {way} {_speed_word(p['speed'], rng)}"


def _jog(p: dict, rng: Rng) -> str:
    phrase = _pick(rng, ("<trot> forward", "<trot> ahead", "<go> for a jog forward",
                         "<run> lightly ahead", "<jog> onward", "<trot> onward"))
    extra = {"slow": ("slowly", "gently"), "normal": ("", "at a steady pace"),
             "fast": ("quickly", "at a good clip")}[p.get("speed", "normal")]
    return f"{phrase} {_pick(rng, extra)}"


def _run(p: dict, rng: Rng) -> str:
    fast = p.get("speed", "normal") == "fast"
    phrase = _pick(rng, ("<sprint> forward", "<race> ahead", "<rush> forward", "<run> onward",
                         "<sprint> ahead") + (("<run> ahead as fast as possible",) if fast else ()))
    return f"{phrase} {'quickly' if fast and rng.random() < 0.5 else ''}"


def _walk_backward(p: dict, rng: Rng) -> str:
    phrase = _pick(rng, ("<retreat> backwards", "<retreat> a few steps", "<back> away",
                         "<step> back a few paces", "<move> away backwards"))
    return f"{phrase} {_speed_word(p['speed'], rng)}"


def _side_step(p: dict, rng: Rng) -> str:
    s, n = p["side"], p["steps"]
    return _pick(rng, (f"<slide> over to the {s}", f"<slide> {_num(n, rng)} steps to HIS {s}",
                       f"<shuffle> sideways toward the {s}", f"<step> out to the {s} side "
                       f"{_times(n, rng)}", f"<move> sideways to HIS {s} with small steps",
                       f"<slide> sideways to the {s} {_times(n, rng)}"))


def _turn(p: dict, rng: Rng) -> str:
    s, angle = p["side"], p["angle"]
    d = _pick(rng, _DEGREES[angle])
    general = (f"<rotate> {d} to HIS {s}", f"<swivel> {d} to the {s}", f"<twist> {d} {s}")
    special = {
        45: (f"<turn> a little to the {s}", f"<twist> slightly to HIS {s}",
             f"<swivel> a bit to the {s}"),
        90: (f"<rotate> to face the {s}", f"<swivel> round to HIS {s}", f"<face> HIS {s}",
             f"<twist> round to face the {s}", f"<turn> to face the {s}"),
        135: (f"<swivel> most of the way round to the {s}", f"<rotate> sharply to HIS {s}"),
        180: (f"<turn> to face the other way, over HIS {s} shoulder",
              f"<swivel> all the way round to the {s}", f"<face> the opposite way, turning {s}",
              f"<turn> back the way they came, to the {s}"),
    }[angle]
    return _pick(rng, general + special + special)


def _circle(p: dict, rng: Rng) -> str:
    s, rot = p["side"], _ROTATION[p["side"]]
    return _pick(rng, (f"<walk> around in a loop to the {s}", f"<loop> around to the {s}",
                       f"<go> round in a circle {rot}", f"<walk> a round path to the {s}",
                       f"<walk> a full lap of a circle to HIS {s}", "<walk> around in a loop"))


def _jump(p: dict, rng: Rng) -> str:
    n, t = p["count"], _times(p["count"], rng)
    if p["mode"] == "in_place":
        return _pick(rng, (f"<leap> up into the air {t}", f"<spring> off both feet {t}",
                           f"<spring> straight up {t}", f"<do> {_n_of(n, 'leap', 'leaps', rng)} "
                           "on the spot", f"<jump> up high {t}")
                     + ((f"<bounce> up and down on both feet {t}",) if n > 1 else ()))
    return _pick(rng, (f"<bound> forward {t}", f"<bound> ahead with both feet together {t}",
                       f"<spring> forward off both feet {t}", f"<leap> ahead {t}"))


def _hop(p: dict, rng: Rng) -> str:
    s, t = p["leg"], _times(p["count"], rng)
    return _pick(rng, (f"<bounce> on the {s} foot {t}", f"<hop> up and down on the {s} leg {t}",
                       f"<spring> up off the {s} leg alone {t}", f"<hop> on just the {s} foot {t}",
                       f"<bounce> {t} on HIS {s} leg"))


def _squat(p: dict, rng: Rng) -> str:
    n, t = p["count"], _times(p["count"], rng)
    return _pick(rng, (f"<bend> the knees, <drop> low and <rise> {t}",
                       f"<do> {_n_of(n, 'deep knee bend', 'deep knee bends', rng)}",
                       f"<sink> down low and <come> back up {t}", f"<lower> the hips and "
                       f"<stand> up {t}", f"<drop> into a squat {t}"))


def _sit_stand(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<lower> onto a seat and <get> back up", "<sit> on a chair and <rise>",
                       "<settle> into a chair and <get> up again",
                       "<take> a seat for a moment, then <stand>"))


def _wave(p: dict, rng: Rng) -> str:
    hand, t = _hand(p["hand"], rng), _times(p["count"], rng)
    return _pick(rng, (f"<greet> someone by waving {hand} {t}", f"<say> goodbye with {hand}",
                       f"<wave> hello with {hand} {t}", f"<signal> with {hand} over HIS head",
                       f"<wave> goodbye with {hand} {t}"))


def _raise_arms(p: dict, rng: Rng) -> str:
    arm = _hand(p["hand"], rng, limb="arm")
    return _pick(rng, (f"<lift> {arm} up high", f"<reach> {arm} toward the sky",
                       f"<hold> {arm} up", f"<stick> {arm} up in the air",
                       f"<put> {arm} up high"))


def _clap(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, ("<applaud>", f"<applaud> {t}", f"<slap> the palms together {t}",
                       f"<bring> HIS hands together {t}", f"<clap> the palms together {t}"))


def _punch(p: dict, rng: Rng) -> str:
    s, n, t = p["hand"], p["count"], _times(p["count"], rng)
    return _pick(rng, (f"<jab> with the {s} fist {t}", f"<strike> forward with the {s} fist {t}",
                       f"<hit> out with HIS {s} hand {t}", f"<fire> {_n_of(n, f'{s} jab', f'{s} jabs', rng)}")
                 + ((f"<throw> a {s} hook",) if n == 1 else ()))


def _kick(p: dict, rng: Rng) -> str:
    s, t = p["leg"], _times(p["count"], rng)
    return _pick(rng, (f"<strike> out with the {s} foot {t}", f"<boot> a ball with the {s} foot {t}",
                       f"<swing> the {s} leg out in a kick {t}", f"<kick> an imaginary ball with "
                       f"HIS {s} foot {t}", f"<boot> forward with the {s} leg {t}"))


def _bow(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<bend> forward at the waist politely", "<bow> to an audience",
                       "<lean> forward in a bow", "<bow> respectfully", "<bow> the upper body"))


def _stretch(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<loosen> up by reaching the arms overhead and leaning to one side",
                       "<warm> up with an overhead side stretch",
                       "<reach> the arms high and <tilt> to the side",
                       "<stretch> out, arms over the head, leaning sideways"))


def _spin(p: dict, rng: Rng) -> str:
    s, rot = p["side"], _ROTATION[p["side"]]
    return _pick(rng, (f"<twirl> around to the {s}", f"<twirl> {rot}", f"<whirl> around to HIS {s}",
                       f"<rotate> a full circle to the {s}", f"<spin> on the spot to the {s}",
                       f"<whirl> {rot} once"))


def _kneel(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<drop> onto the {s} knee and <get> up", f"<go> down on the {s} knee",
                       f"<lower> onto HIS {s} knee, then <rise>", f"<plant> the {s} knee on the "
                       "ground and <stand> again"))


def _stand(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<wait> without moving", "<remain> still", "<hold> still",
                       "<keep> perfectly still", "<remain> in place", "<wait> calmly"))


PHRASES: dict[str, Callable[[dict, Rng], str]] = {
    "walk": _walk, "jog": _jog, "run": _run, "walk_backward": _walk_backward,
    "side_step": _side_step, "turn": _turn, "circle": _circle, "jump": _jump, "hop": _hop,
    "squat": _squat, "sit_stand": _sit_stand, "wave": _wave, "raise_arms": _raise_arms,
    "clap": _clap, "punch": _punch, "kick": _kick, "bow": _bow, "stretch": _stretch,
    "spin": _spin, "kneel": _kneel, "stand": _stand,
    **MORE_PHRASES,  # the families of benchmark version 3
    **{f: phrase for m in VERSION_4_MODULES for f, phrase in m.PHRASES["everyday"].items()},
}
assert set(PHRASES) == set(FAMILIES)

SUBJECTS = (("somebody", "their"), ("a guy", "his"), ("a girl", "her"), ("a kid", "their"),
            ("an athlete", "their"), ("a dancer", "their"), ("the character", "their"),
            ("an old man", "his"), ("a young woman", "her"), ("a person", "their"),
            ("the man", "his"), ("a lady", "her"))

EVERYDAY = Vocabulary(PHRASES, SUBJECTS, FORMS)
# Every subject a training caption uses (the benchmark's and these, once each): the short and
# colloquial vocabularies draw from it, and the generator reads any other as "a person"
# (generate/compose.py: plain_subject).
ALL_SUBJECTS = tuple(dict.fromkeys(_SUBJECTS + SUBJECTS))
