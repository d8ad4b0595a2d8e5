"""Colloquial captions for procedural motions: the sentence forms the other vocabularies lack.

The second held-out paraphrase set (bench/data/quality_prompts_heldout2.json, 0.823 of its
read-outs passed) failed in four ways no training caption had shown the model (docs/model_card.md):
- words it never saw ("sidles");
- a turn's size said in words ("a quarter turn", "half a turn"), never in degrees;
- a side said after its noun ("on one knee, the left one", "with a hand, the right");
- negation ("does not move", "without turning around").
This vocabulary says every family in those forms, and in other uncommon verbs, equally
truthful: a phrase may leave a parameter out but never states a wrong side, count, angle, speed
or order. A turn's size in words is said only where the word means one angle: a quarter turn
is 90 degrees, a half turn 180, an eighth of a turn 45; a turn said without its size is a
quarter turn, as in the benchmark's captions. A first version said "turns left without stepping
away" of every size and "a complete about-face" of half turns: 6,000 steps on it made "turning
ninety degrees left" a 50-degree turn and "a complete rotation to the right" (a spin) stand
still in 2 seeds of 5 (docs/training.md). A turn word is said only of
motions that turn: "steps backwards without turning round" and "edges along without turning"
(348 training captions) paired "turning" with motions that do not turn. Runs without them still
moved turns' sizes; seeing the turns more often held them best (docs/training.md).

It was written after held-out set 2's failures were read, so that set no longer measures unseen
sentence forms for those four classes; the third set (quality_prompts_heldout3.json) was written
by another author who had not read any vocabulary, before this one was trained on.

`mlct data rephrase SRC --vocabulary colloquial` adds captions made with it to a training split.
"""

from __future__ import annotations

from collections.abc import Callable

from mlct.data.synth.actions import VERSION_4_MODULES
from mlct.data.synth.everyday import ALL_SUBJECTS
from mlct.data.synth.everyday import FORMS as EVERYDAY_FORMS
from mlct.data.synth.phrases_more import COLLOQUIAL as MORE_PHRASES
from mlct.data.synth.phrases_more import COLLOQUIAL_VERBS as MORE_VERBS
from mlct.data.synth.text import _ROTATION, FAMILIES, Rng, Vocabulary, _num, _pick, _times

# Verbs this vocabulary adds, with (third person, gerund). The "not..." entries are negations
# said as one verb, so a sentence's other forms conjugate them ("is not moving", "before
# keeping still").
_NEW_VERBS = {
    "sidle": ("sidles", "sidling"), "edge": ("edges", "edging"), "crab": ("crabs", "crabbing"),
    "saunter": ("saunters", "sauntering"), "plod": ("plods", "plodding"),
    "trudge": ("trudges", "trudging"), "tread": ("treads", "treading"),
    "lope": ("lopes", "loping"), "pad": ("pads", "padding"), "bolt": ("bolts", "bolting"),
    "tear": ("tears", "tearing"), "backpedal": ("backpedals", "backpedalling"),
    "vault": ("vaults", "vaulting"), "hunker": ("hunkers", "hunkering"),
    "perch": ("perches", "perching"), "flag": ("flags", "flagging"),
    "box": ("boxes", "boxing"), "punt": ("punts", "punting"), "lash": ("lashes", "lashing"),
    "incline": ("inclines", "inclining"), "limber": ("limbers", "limbering"),
    "pirouette": ("pirouettes", "pirouetting"), "genuflect": ("genuflects", "genuflecting"),
    "curve": ("curves", "curving"), "cheer": ("cheers", "cheering"),
    "notmove": ("does not move", "not moving"), "notbudge": ("does not budge", "not budging"),
    "notstir": ("doesn't stir", "not stirring"), "notmovex": ("doesn't move", "not moving"),
}
_NEW_VERBS.update(MORE_VERBS)
for _module in VERSION_4_MODULES:
    _NEW_VERBS.update(_module.VERBS["colloquial"])
COLLOQUIAL_VERBS = frozenset(v for v in _NEW_VERBS if not v.startswith("not"))
FORMS: dict[str, tuple[str, str]] = {**EVERYDAY_FORMS, **_NEW_VERBS}  # the benchmark's too

# A turn's size in words: only words that mean one angle.
_SIZE_WORDS = {
    45: ("an eighth of a turn", "a small turn", "a slight turn"),
    90: ("a quarter turn", "a quarter of a turn", "a quarter turn", "a right-angle turn"),
    135: ("a sharp turn", "more than a quarter turn but less than a half turn"),
    180: ("a half turn", "half a turn", "a half turn", "an about-face"),
}


def _one(side: str, noun: str, rng: Rng) -> str:
    """A side said after its noun: 'one knee, the left one', 'a hand, the right'."""
    article = "an" if noun[0] in "aeiou" else "a"
    return _pick(rng, (f"one {noun}, the {side} one", f"{article} {noun}, the {side} one",
                       f"one {noun}, the {side}", f"the {noun} on the {side}",
                       f"the {noun} on HIS {side} side"))


def _walk(p: dict, rng: Rng) -> str:
    verb = _pick(rng, {"slow": ("saunter", "plod", "trudge"),
                       "normal": ("tread", "make", "walk"),
                       "fast": ("stride", "march", "walk")}[p["speed"]])
    way = "HIS way forward on foot" if verb == "make" else _pick(
        rng, ("forward", "ahead", "forward in a line", "along, facing forward"))
    speed = {"slow": ("slowly", "without any hurry", "not hurrying at all", ""),
             "normal": ("", "", "without running", "not running, just walking"),
             "fast": ("quickly", "briskly", "fast on foot")
             }[p["speed"]]
    return f"<{verb}> {way} {_pick(rng, speed)}"


def _jog(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<lope> forward", "<pad> forward at a jog", "<jog> ahead, not sprinting",
                       "<run> forward gently, not flat out", "<lope> ahead at an easy jog",
                       "<jog> forward without stopping"))


def _run(p: dict, rng: Rng) -> str:
    fast = p.get("speed", "normal") == "fast"
    return _pick(rng, ("<bolt> forward", "<tear> off forward", "<dash> ahead",
                       "<run> forward, not walking", "<bolt> ahead running")
                 + (("<run> flat out", "<tear> ahead at full speed") if fast else ()))


def _walk_backward(p: dict, rng: Rng) -> str:
    speed = {"slow": ("slowly", "carefully, a step at a time"), "normal": ("", ""),
             "fast": ("quickly", "in a hurry")}[p["speed"]]
    phrase = _pick(rng, ("<backpedal>", "<backpedal> a few steps", "<walk> backwards, facing "
                         "the front the whole time", "<step> backwards, eyes to the front",
                         "<back> up without looking behind", "<walk> back, still facing ahead"))
    return f"{phrase} {_pick(rng, speed)}"


def _side_step(p: dict, rng: Rng) -> str:
    s, n = p["side"], p["steps"]
    return _pick(rng, (f"<sidle> to the {s}", f"<sidle> over to HIS {s}", f"<edge> sideways to "
                       f"the {s}", f"<crab> sideways to the {s}", f"<sidle> {_num(n, rng)} steps, "
                       f"going {s}", f"<step> sideways {_times(n, rng)}, to the {s}",
                       f"<edge> along to the {s}, chest to the front", f"<move> sideways, toward "
                       f"the {s}, facing front"))


def _turn(p: dict, rng: Rng) -> str:
    s, angle = p["side"], p["angle"]
    size = _pick(rng, _SIZE_WORDS[angle])
    # "turns left" / "turning left" (not "turns left by ...") is said only of quarter turns, as
    # in the benchmark's captions: said of every size, it made "turning ninety degrees left" a
    # 50-degree turn (docs/training.md)
    forms = [f"<make> {size} to the {s}", f"<do> {size} to HIS {s}", f"<make> {size}, going {s}",
             f"<turn> {s} by {size}", f"<turn> on the spot, {size} to the {s}",
             f"<pivot> {size} to the {s}"]
    if angle == 180:
        forms += [f"<turn> to face the way they came, going {s}", f"<turn> all the way round, "
                  f"to the {s}"]
    if angle == 90:  # a turn said without its size is a quarter turn, as in the benchmark
        forms += [f"<turn> so that what was on HIS {s} is now in front",
                  f"<turn> {s} without stepping away", f"<turn> {s}, {size}"]
    return _pick(rng, forms)


def _circle(p: dict, rng: Rng) -> str:
    s, rot = p["side"], _ROTATION[p["side"]]
    return _pick(rng, (f"<walk> a full circle, curving {s}", f"<walk> around in a ring, "
                       f"bearing {s}", f"<curve> round in a circle to the {s}",
                       f"<walk> a lap, turning {s} all the way", f"<walk> in a circle, going "
                       f"{rot}"))


def _jump(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    if p["mode"] == "in_place":
        return _pick(rng, (f"<vault> straight up {t}", f"<jump> on the spot {t}, both feet "
                           "off the ground", f"<jump> up {t} without moving forward",
                           f"<leap> up {t}, landing where they started"))
    return _pick(rng, (f"<leap> forward {t}, feet together", f"<vault> ahead {t}",
                       f"<jump> forward {t}, landing further on"))


def _hop(p: dict, rng: Rng) -> str:
    s, t = p["leg"], _times(p["count"], rng)
    # the negated form names the hopping foot, never the raised one: "without putting the right
    # foot down" of a left hop is read near "hops on the right foot" (cosine 0.67 against 0.35,
    # the side-contrast encoder counts side words, not whose foot), and with it in the captions
    # every recipe model hopped on the right when asked for the left (bench/quality.py sides)
    return _pick(rng, (f"<hop> {t} on {_one(s, 'leg', rng)}",
                       f"<hop> on {_one(s, 'foot', rng)} {t}",
                       f"<hop> {t} on the {s} foot without putting the other one down",
                       f"<balance> on the {s} foot alone and <hop> {t}"))


def _squat(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<crouch> down and <stand> {t}", f"<hunker> down and <rise> {t}",
                       f"<bend> at the knees until low, then <straighten> up {t}",
                       f"<go> down into a crouch and back up {t}"))


def _sit_stand(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<perch> on a chair, then <get> back up", "<sit> for a second and "
                       "<stand> again", "<drop> onto a stool and <rise>", "<sit> down, not for "
                       "long, and <get> up"))


def _hand_late(hand: str, noun: str, rng: Rng) -> str:
    if hand == "both":
        return _pick(rng, (f"both {noun}s", f"both HIS {noun}s", f"HIS {noun}s, both of them"))
    return _one(hand, noun, rng)


def _wave(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    hand = _hand_late(p["hand"], "hand", rng)
    forms = [f"<wave> {t} with {hand}", f"<wave> {hand} {t}", f"<flag> someone down, waving "
             f"{hand} {t}"]
    if p["hand"] != "both":
        forms += [f"<wave> {t}, using the {p['hand']} hand", f"<wave> {t}, the {p['hand']} "
                  "hand up, the other down"]
    return _pick(rng, forms)


def _raise_arms(p: dict, rng: Rng) -> str:
    if p["hand"] == "both":
        return _pick(rng, ("<throw> both arms up", "<raise> both arms as if cheering",
                           "<cheer> with both arms up", "<lift> HIS arms, both of them, overhead"))
    arm = _one(p["hand"], "arm", rng)
    return _pick(rng, (f"<raise> {arm}", f"<lift> {arm} up high", f"<put> a hand up, the "
                       f"{p['hand']} one, as if asking a question", f"<raise> {arm}, keeping "
                       "the other down"))


def _clap(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<clap> {t}, palms meeting in front of the chest", f"<put> HIS hands "
                       f"together {t}", f"<bring> the palms together {t}, clapping"))


def _punch(p: dict, rng: Rng) -> str:
    s, n, t = p["hand"], p["count"], _times(p["count"], rng)
    return _pick(rng, (f"<punch> {t} with {_one(s, 'fist', rng)}", f"<box> with the {s} hand "
                       f"{t}", f"<jab> the air {t}, {s} fist", f"<throw> "
                       f"{'a punch' if n == 1 else _num(n, rng) + ' punches'}, all with "
                       f"the {s} hand"))


def _kick(p: dict, rng: Rng) -> str:
    s, t = p["leg"], _times(p["count"], rng)
    return _pick(rng, (f"<kick> {t} with {_one(s, 'leg', rng)}", f"<kick> out {t}, {s} foot",
                       f"<punt> an imaginary ball with the {s} foot {t}",
                       f"<lash> out with a kick of {_one(s, 'leg', rng)} {t}"))


def _bow(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<bow> deeply", "<take> a bow", "<incline> the torso forward in a bow",
                       "<bow> from the hips, not just the head"))


def _stretch(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<limber> up, arms above the head, leaning over", "<reach> up and over "
                       "to one side", "<stretch> sideways with the arms overhead",
                       "<stretch> the arms up and <lean> to one side"))


def _spin(p: dict, rng: Rng) -> str:
    s, rot = p["side"], _ROTATION[p["side"]]
    return _pick(rng, (f"<pirouette> to the {s}", f"<pirouette> {rot}", f"<spin> a whole turn "
                       f"on the spot, to the {s}", f"<spin> all the way round once, going {s}",
                       f"<spin> full circle, {s}wards"))


def _kneel(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<kneel> on {_one(s, 'knee', rng)}", f"<genuflect> on the {s} knee",
                       f"<drop> to {_one(s, 'knee', rng)} and <get> up", f"<kneel>, the {s} "
                       "knee on the ground, then <rise>", f"<genuflect>, {s} knee down"))


def _stand(p: dict, rng: Rng) -> str:
    return _pick(rng, ("<notmove>", "<notmove> at all", "<notmovex>", "<notmovex> at all",
                       "<notbudge>", "<notstir>", "<stand> without moving", "<stay> put, not "
                       "moving", "<do> nothing at all", "<stand> there and <notmove>"))


# Where and to whom: words that change nothing in the motion. A prompt's pooled vector drifts
# with every word it holds, so "a boy waves across the street to his mother, using his left
# hand" waved the right hand where "a boy waves, using his left hand" waved the left (5 of 5).
# Captions with such words were meant to teach the model to read past them; 2,500 steps on them
# did not cure that prompt (docs/training.md), so the shipped
# model was not trained on them. Places go with any action, addressees with the arm actions one
# does for someone.
_PLACES = ("in the park", "in the kitchen", "on the beach", "in the gym", "on a stage",
           "in the hallway", "in the garden", "in the rain", "on the pavement",
           "in an empty room", "at the bus stop", "in front of the mirror")
_ADDRESSEES = ("to a friend across the street", "to HIS mother", "at the camera",
               "for the crowd", "to the audience", "across the room", "to a neighbour",
               "for the children")
_FOR_SOMEONE = frozenset({"wave", "clap", "bow", "raise_arms"})
CONTEXT_SHARE = 0.35  # of phrases that carry a place or an addressee


def _with_context(family: str, maker: Callable[[dict, Rng], str]) -> Callable[[dict, Rng], str]:
    """`maker`'s phrase, sometimes with a place or an addressee: at its end, or before its last
    comma clause ("<wave> to a friend across the street, using HIS left hand")."""
    words = _PLACES + (_ADDRESSEES if family in _FOR_SOMEONE else ())

    def phrase(p: dict, rng: Rng) -> str:
        said = maker(p, rng)
        if rng.random() >= CONTEXT_SHARE:
            return said
        context = _pick(rng, words)
        if ", " in said and rng.random() < 0.5:
            head, tail = said.rsplit(", ", 1)
            return f"{head} {context}, {tail}"
        return f"{said} {context}"
    return phrase


PHRASES: dict[str, Callable[[dict, Rng], str]] = {
    "walk": _walk, "jog": _jog, "run": _run, "walk_backward": _walk_backward,
    "side_step": _side_step, "turn": _turn, "circle": _circle, "jump": _jump, "hop": _hop,
    "squat": _squat, "sit_stand": _sit_stand, "wave": _wave, "raise_arms": _raise_arms,
    "clap": _clap, "punch": _punch, "kick": _kick, "bow": _bow, "stretch": _stretch,
    "spin": _spin, "kneel": _kneel, "stand": _stand,
    **MORE_PHRASES,  # the families of benchmark version 3
    **{f: phrase for m in VERSION_4_MODULES for f, phrase in m.PHRASES["colloquial"].items()},
}
assert set(PHRASES) == set(FAMILIES)

COLLOQUIAL = Vocabulary(PHRASES, ALL_SUBJECTS, FORMS)
# the same phrases, CONTEXT_SHARE of them with a place or an addressee (`--vocabulary context`)
CONTEXT = Vocabulary({family: _with_context(family, maker) for family, maker in PHRASES.items()},
                     ALL_SUBJECTS, FORMS)
