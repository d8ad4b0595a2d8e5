"""Whole-body families of benchmark version 4: crawling, stairs, falls, carrying and pushing,
uneven and balancing walks, jumps.

Every family module of version 4 (this one, families_arms.py) has the same interface, which
actions.py, more_clips.py, the four vocabularies (text.py, everyday.py, colloquial.py, short.py)
and the caption lexicon (mlct.data.captions) merge; the module imports none of them, so that
each of those can take its entries from here:

- PARAMS: family -> {parameter: its possible values} (actions.FAMILY_PARAMS);
- CLIPS: family -> clip function (rig, fps, style, **params) -> motions.Clip, as more_clips';
- PHRASES: vocabulary ("benchmark", "everyday", "colloquial", "short") -> family -> phrase
  (params, rng) -> str, with the <verb> marks and HIS of text.py and each vocabulary's rules
  (phrases_more.py);
- VERBS: vocabulary ("benchmark", "everyday", "colloquial") -> lemma -> (third person,
  gerund) of the verbs its phrases mark that the vocabulary lacks (the short vocabulary uses
  the benchmark's);
- WORDS: word -> part of speech (NOUN, ADJ, ADV, ADP, ...) and PLURALS: plural -> singular,
  the other words of its benchmark captions that the lexicon lacks;
- ENDS_DOWN / STARTS_DOWN: families that end on the floor (nothing follows them in a script)
  and that start lying on the back (first in a script, or right after lying down).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from mlct.data.synth.motions import (Clip, Style, _arm, _frames, bump, ease, gait, hip_wave,
                                    hold, neutral)
from mlct.data.synth.phrases_more import Phrase, Rng, _count, _pick, _table, _times
from mlct.data.synth.rig import SIDES, Rig, pose_positions, rot_x

# ---------------------------------------------------------------------------- walks with the arms busy
# Wrist targets are in the chest frame relative to the shoulder (rig.pose_positions): x to the
# body's left, y up, z forward, metres; `sign` is +1 for the left arm and -1 for the right.


def _walk(fps: float, style: Style, kind: str, strides: float, stride_scale: float = 1.0) -> Clip:
    """A walk of `kind` (motions.gait) with the hip swing scaled by `stride_scale`."""
    return gait(fps, replace(style, amplitude=style.amplitude * stride_scale), kind, strides)


def _held(clip: Clip, fps: float, ramp: float = 0.45) -> np.ndarray:
    """Weight of a pose of the arms held over the whole clip, eased in and out over `ramp` s."""
    t = np.arange(clip.n) / fps
    return ease(t / ramp) * ease((t[-1] - t) / ramp)


def carry(rig: Rig, fps: float, style: Style) -> Clip:
    """Walks forward carrying a box in both hands: the wrists a box's width apart in front of
    the belly, the elbows bent and down, the steps a little shorter."""
    clip = _walk(fps, style, "slow", 3 + style.tempo, 0.85)
    up = _held(clip, fps)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # 0.17 m either side of the midline, 0.3 m below and in front of the shoulders.
        wrist = np.array([-sign * (style.shoulder_x - 0.17), -0.3, 0.33])
        _arm(clip, side, wrist, up, np.array([sign * 0.6, -1.0, -0.2]))
    clip.channels["spine_bend"] = clip.channels["spine_bend"] - 0.06 * up  # leaning back a touch
    return clip


def push(rig: Rig, fps: float, style: Style) -> Clip:
    """Pushes something heavy forward: slow short steps, the body leant in, both arms
    reaching forward at chest height with the elbows a little bent."""
    clip = _walk(fps, replace(style, tempo=style.tempo * 0.85), "slow", 3 + style.tempo, 0.7)
    up = _held(clip, fps, 0.6)
    ch = clip.channels
    ch["spine_bend"] = ch["spine_bend"] + 0.32 * up
    ch["head_nod"] = ch["head_nod"] - 0.2 * up  # looking ahead, not at the floor
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # Level with the shoulders once leant in (the chest frame is tipped forward).
        wrist = np.array([-sign * (style.shoulder_x - 0.2), 0.1, 0.88 * style.arm_length])
        _arm(clip, side, wrist, up, np.array([sign, -1.0, 0.0]))
    return clip


def balance_walk(rig: Rig, fps: float, style: Style) -> Clip:
    """Walks slowly, carefully, with both arms held straight out to the sides for balance,
    rocking a little."""
    clip = _walk(fps, replace(style, tempo=style.tempo * 0.9), "slow", 3 + style.tempo, 0.75)
    up = _held(clip, fps, 0.6)
    t = np.arange(clip.n) / fps
    rock = 0.06 * np.sin(2 * np.pi * 0.6 * t)  # the arms see-saw as the balance is kept
    for side, sign in (("left", 1.0), ("right", -1.0)):
        length = 0.95 * style.arm_length
        wrist = np.stack([np.full(clip.n, sign * length), -0.04 + sign * rock,
                          np.full(clip.n, 0.03)], -1)
        _arm(clip, side, wrist, up, np.array([0.0, -0.3, -1.0]))
    clip.channels["spine_side"] = clip.channels["spine_side"] + 0.6 * rock * up
    return clip


# ---------------------------------------------------------------------------- stairs
# Stairs are stepped foot over foot, one tread a step, as most adults do; the legs are posed by
# inverse kinematics from the feet's paths over the treads, and the ground channels say which
# tread each foot is over, so that compose.place_on_ground stands each foot on its own step.

RISER, TREAD = 0.17, 0.28  # metres: a common domestic stair
STAIR_STEPS = 4  # treads climbed or descended


def _leg_angles(rig: Rig, hip: np.ndarray, ankle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(hip flexion, knee flexion), each (T,), that put the ankle at `ankle` (T, 3) from the
    hip joint at `hip` (3,) in the body frame (the sagittal plane; the bones' rest tilt kept)."""
    sk = rig.skeleton
    thigh = sk.bone_lengths[rig.knee["left"]] / rig.scale
    shin = sk.bone_lengths[rig.ankle["left"]] / rig.scale
    rest_thigh, rest_shin = (sk.rest_directions[rig.knee["left"]],
                             sk.rest_directions[rig.ankle["left"]])
    tilt_thigh = np.arctan2(rest_thigh[2], -rest_thigh[1])  # forward of straight down
    tilt_shin = np.arctan2(rest_shin[2], -rest_shin[1])
    dz, dy = ankle[:, 2] - hip[2], ankle[:, 1] - hip[1]
    reach = np.clip(np.hypot(dz, dy), abs(thigh - shin) + 1e-6, 0.999 * (thigh + shin))
    toward = np.arctan2(dz, -dy)  # direction hip -> ankle, forward of straight down
    bend = np.arccos(np.clip((thigh**2 + reach**2 - shin**2) / (2 * thigh * reach), -1, 1))
    a_thigh = toward + bend  # the knee in front of the line hip -> ankle
    knee_at = np.stack([thigh * np.sin(a_thigh), -thigh * np.cos(a_thigh)], -1)
    lower = np.stack([np.sin(toward), -np.cos(toward)], -1) * reach[:, None] - knee_at
    a_shin = np.arctan2(lower[:, 0], -lower[:, 1])
    hip_flex = a_thigh - tilt_thigh
    return hip_flex, hip_flex + tilt_shin - a_shin


def _smooth(x: np.ndarray, fps: float, seconds: float) -> np.ndarray:
    """`x` (T,) smoothed by a Gaussian of `seconds` s (the ends held)."""
    k = max(1, int(round(2 * seconds * fps)))
    kernel = np.exp(-0.5 * (np.arange(-k, k + 1) / (seconds * fps)) ** 2)
    padded = np.concatenate([np.repeat(x[:1], k), x, np.repeat(x[-1:], k)])
    return np.convolve(padded, kernel / kernel.sum(), mode="valid")


def _stairs(rig: Rig, fps: float, style: Style, rise: float) -> Clip:
    """Walks STAIR_STEPS treads up (rise > 0) or down (rise < 0, metres a step) foot over foot,
    the last step bringing the feet together on the last tread."""
    tempo = style.tempo
    step = (0.62 if rise < 0 else 0.72) / tempo  # seconds a step
    swing = 0.8 * step
    n, t = _frames(0.3 + (STAIR_STEPS + 1) * step + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    rest = pose_positions(rig, neutral(1, style).channels)[0] / rig.scale
    feet = {s: np.tile(rest[rig.ankle[s]], (n, 1)) for s in SIDES}
    treads = {s: np.zeros(n) for s in SIDES}
    lift = 0.05 if rise < 0 else 0.07
    for i in range(1, STAIR_STEPS + 2):  # step i lands on tread i, the last joins the other foot
        side = SIDES[(i + 1) % 2]
        tread = min(i, STAIR_STEPS)
        t0 = 0.3 + (i - 1) * step
        u = np.clip((t - t0) / swing, 0, 1)
        start = feet[side][np.searchsorted(t, t0)].copy()
        goal = rest[rig.ankle[side]] + np.array([0.0, rise * tread, TREAD * tread])
        if rise < 0:  # down: out over the edge first, then down onto the tread
            along, up = ease(u), ease((u - 0.25) / 0.75)
        else:  # up: lift over the riser first, then forward onto the tread
            along, up = ease((u - 0.2) / 0.8), ease(u / 0.6)
        later = t >= t0
        feet[side][later, 2] = start[2] + (goal[2] - start[2]) * along[later]
        feet[side][later, 1] = start[1] + (goal[1] - start[1]) * up[later] \
            + lift * np.sin(np.pi * u[later])
    for s in SIDES:  # the tread under the middle of each foot
        over = np.floor((feet[s][:, 2] + 0.06 - rest[rig.ankle[s], 2]) / TREAD + 0.5)
        treads[s] = np.clip(over, 0, STAIR_STEPS) * rise
    # The pelvis: over the feet, as high as the lower foot lets it (the upper knee bends),
    # 4 cm down on straight legs so that the lower foot reaches its tread ahead or behind.
    low = np.minimum(feet["left"][:, 1], feet["right"][:, 1]) - rest[rig.ankle["left"], 1]
    pelvis = np.stack([np.zeros(n), _smooth(low, fps, 0.1) - 0.04 * hold(t - 0.1, 0.3, n / fps - 0.8, 0.3),
                       _smooth(0.5 * (feet["left"][:, 2] + feet["right"][:, 2])
                               - rest[rig.ankle["left"], 2], fps, 0.1)], -1)
    for side in SIDES:
        s = side[0]
        target = feet[side] - pelvis
        target[:, 0] = rest[rig.ankle[side], 0]
        hip, knee = _leg_angles(rig, rest[rig.hip[side]], target)
        ch[f"hip_flex_{s}"], ch[f"knee_{s}"] = hip, knee
        airborne = feet[side][:, 1] - rest[rig.ankle[side], 1] - treads[side] > 0.01
        ch[f"ankle_{s}"] = knee - hip + (0.25 if rise > 0 else -0.1) * airborne  # flat on a tread
        ch[f"ground_{s}"] = treads[side]
    ch["spine_bend"] = (0.16 if rise > 0 else 0.06) * hold(t - 0.1, 0.4, n / fps - 0.9, 0.4)
    phase = np.pi * np.clip(t - 0.3, 0, None) / step
    for side, sign in (("left", 1.0), ("right", -1.0)):  # a small swing against the legs
        wrist = np.stack([np.full(n, 0.04 * sign), np.full(n, -0.93 * style.arm_length),
                          0.03 + 0.1 * sign * np.sin(phase)], -1)
        _arm(clip, side, wrist, hold(t - 0.1, 0.4, n / fps - 0.9, 0.4))
    return clip


def walk_downstairs(rig: Rig, fps: float, style: Style) -> Clip:
    """Walks down a flight of STAIR_STEPS stairs, a foot to each step."""
    return _stairs(rig, fps, style, -RISER)


def walk_upstairs(rig: Rig, fps: float, style: Style) -> Clip:
    """Walks up a flight of STAIR_STEPS stairs, a foot to each step, leaning into them."""
    return _stairs(rig, fps, style, RISER)


# ---------------------------------------------------------------------------- on the floor

CRAWL_PITCH = 1.5  # body_pitch on hands and knees: the shoulders a little higher than the hips
CRAWL_SWING = 0.28  # radians the thigh swings either side of vertical: 0.2 m a stride


def _hands_down(rig: Rig, clip: Clip, reach: dict[str, np.ndarray],
                lift: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Wrist targets (chest frame) that put each hand on the floor under its shoulder, `reach`
    (T,) metres ahead of it and `lift` (T,) metres up, in each frame's pose; the floor is where
    the legs meet it (the lowest of their floor points, less the flesh)."""
    body = pose_positions(rig, clip.channels) / rig.scale
    legs = [j for j in rig.floor_points if j not in (*rig.wrist.values(), *rig.elbow.values())]
    flesh = np.array([rig.floor_points[j] for j in legs])
    floor = (body[:, legs, 1] - flesh).min(axis=1)
    chest = rot_x(clip.channels["body_pitch"]) @ rot_x(clip.channels["spine_bend"])
    targets = {}
    for side in SIDES:
        shoulder = body[:, rig.shoulder[side]]
        hand = np.stack([shoulder[:, 0], floor + rig.floor_points[rig.wrist[side]] + lift[side],
                         shoulder[:, 2] + reach[side]], -1)
        targets[side] = np.einsum("tji,tj->ti", chest, hand - shoulder)  # into the chest frame
    return targets


def crawl(rig: Rig, fps: float, style: Style) -> Clip:
    """Gets down on the hands and knees, crawls forward three strides (each hand with the
    opposite knee, the hands planted under the shoulders), and stands back up."""
    tempo = style.tempo
    down, period, strides = 1.3 / tempo, 1.1 / tempo, 3
    n, t = _frames(0.1 + 2 * down + strides * period + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    on = hold(t - 0.1, down, strides * period, down)  # standing -> on all fours -> standing
    cycles = np.clip(t - 0.1 - down, 0, strides * period) / period
    duty = 0.7
    reach, lift = {}, {}
    for s, hand, offset in (("l", "right", 0.0), ("r", "left", 0.5)):  # a knee with the other hand
        u = np.mod(cycles + offset, 1.0)
        swing = np.clip((u - duty) / (1 - duty), 0, 1) * (cycles > 0) * (cycles < strides)
        wave = CRAWL_SWING * style.amplitude * hip_wave(u, duty) * on
        ch[f"hip_flex_{s}"] = CRAWL_PITCH * on + wave  # the thigh about vertical
        ch[f"hip_abd_{s}"] = 0.25 * bump(swing)  # the swinging knee clears the floor
        ch[f"knee_{s}"] = (np.pi / 2) * on + wave  # the shin along the floor as the thigh swings
        ch[f"ankle_{s}"] = -1.3 * on  # the top of the foot towards the floor
        thigh = rig.skeleton.bone_lengths[rig.knee["left"]] / rig.scale
        reach[hand] = thigh * np.sin(wave) * 0.9
        # A planted hand presses 1 cm into the floor's flesh, so that the hands, not the knees,
        # are the lowest and hold the body (compose.SEAT_GRIP) as it moves over them.
        lift[hand] = 0.07 * bump(swing) - 0.01
    ch["body_pitch"] = CRAWL_PITCH * on
    ch["head_nod"] = -0.55 * on  # looking ahead along the floor
    ch["floor"] = (on > 0.5).astype(float)
    hands = _hands_down(rig, clip, reach, lift)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, hands[side], np.clip(1.6 * on, 0, 1), np.array([sign * 0.3, 1.0, 0.0]))
    return clip


# ---------------------------------------------------------------------------- phrases
# The rules of phrases_more.py: a side is said in the benchmark's words and never the other side,
# a count always (short: never); <verb> marks and HIS as in text.py.

BENCHMARK: dict[str, Phrase] = _table(
    walk_downstairs=("<walk> down the stairs", "<walk> down a flight of stairs",
                     "<go> down the stairs", "<walk> downstairs", "<descend> the stairs",
                     "<walk> down some stairs"),
    walk_upstairs=("<walk> up the stairs", "<climb> the stairs", "<go> up a flight of stairs",
                   "<walk> upstairs", "<climb> up some stairs", "<walk> up a flight of stairs"),
    crawl=("<crawl> forward on HIS hands and knees", "<get> down on all fours and <crawl> forward",
           "<crawl> forward", "<crawl> on the floor on hands and knees",
           "<go> down on HIS hands and knees, <crawl> forward and <stand> up again"),
    carry=("<carry> a box forward with both hands", "<walk> forward carrying a box",
           "<walk> forward holding a box in front of HIS body",
           "<carry> something in both hands and <walk> forward",
           "<walk> ahead with a box in HIS arms", "<hold> a box in both hands and <walk> forward"),
    push=("<push> something heavy forward", "<push> a heavy object forward with both hands",
          "<lean> in and <push> something forward", "<walk> forward slowly pushing something",
          "<push> something ahead of HIS body with both arms"),
    balance_walk=("<walk> forward with HIS arms out to the sides",
                  "<walk> slowly with both arms out to the side",
                  "<walk> carefully with HIS arms spread out",
                  "<balance> with HIS arms out and <walk> forward",
                  "<stretch> HIS arms out to the sides and <walk> forward slowly"),
)

EVERYDAY: dict[str, Phrase] = _table(
    walk_downstairs=("<head> down the staircase", "<make> HIS way down the stairs",
                     "<come> down the steps"),
    walk_upstairs=("<head> up the staircase", "<make> HIS way up the stairs",
                   "<mount> the steps one after another"),
    crawl=("<creep> along the floor on all fours", "<move> ahead on hands and knees like a baby",
           "<drop> to all fours and <shuffle> forward"),
    carry=("<lug> a box along in both arms", "<bring> a box along in front of HIS body",
           "<tote> a box across the room", "<cart> a heavy box forward"),
    push=("<shove> something heavy along", "<heave> a heavy load forward",
          "<lean> into something and <drive> it forward"),
    balance_walk=("<tiptoe> along with HIS arms spread wide",
                  "<inch> forward with HIS arms out like a tightrope walker",
                  "<steady> HIS body with outstretched arms and <walk> on"),
)

COLLOQUIAL: dict[str, Phrase] = _table(
    walk_downstairs=("<trot> down the stairs", "<clatter> down the steps"),
    walk_upstairs=("<trudge> up the stairs", "<clamber> up the steps"),
    crawl=("<scuttle> along on all fours", "<go> across the floor on all fours like a toddler"),
    carry=("<schlep> a box along", "<lug> a big box across the room"),
    push=("<muscle> something heavy forward", "<shove> a load along, leaning into it"),
    balance_walk=("<wobble> along with HIS arms out like on a tightrope",
                  "<totter> ahead, arms flung out"),
)

SHORT: dict[str, Phrase] = _table(
    walk_downstairs=("<walk> downstairs", "<go> down the stairs", "<walk> down stairs"),
    walk_upstairs=("<walk> upstairs", "<climb> stairs", "<go> up the stairs"),
    crawl=("<crawl>", "<crawl>", "<crawl> on all fours"),
    carry=("<carry> a box", "<carry> a box", "<walk> carrying a box"),
    push=("<push> something", "<push> something", "<push> something forward"),
    balance_walk=("<walk> with arms out", "<walk> with HIS arms out"),
)


# ---------------------------------------------------------------------------- the interface

PARAMS: dict[str, dict[str, tuple]] = {
    "crawl": {}, "walk_downstairs": {}, "walk_upstairs": {}, "carry": {}, "push": {}, "balance_walk": {},
}
CLIPS: dict[str, Callable[..., Clip]] = {
    "crawl": crawl, "walk_downstairs": walk_downstairs, "walk_upstairs": walk_upstairs,
    "carry": carry, "push": push, "balance_walk": balance_walk,
}
PHRASES: dict[str, dict[str, Phrase]] = {"benchmark": BENCHMARK, "everyday": EVERYDAY,
                                         "colloquial": COLLOQUIAL, "short": SHORT}


def _forms(*lemmas: str) -> dict[str, tuple[str, str]]:
    """lemma -> (third person, gerund) of regular verbs; a final 'e' dropped in the gerund."""
    def third(v: str) -> str:
        return v + "es" if v.endswith(("s", "sh", "ch", "x", "z", "o")) else (
            v[:-1] + "ies" if v.endswith("y") and v[-2] not in "aeiou" else v + "s")
    return {v: (third(v), (v[:-1] if v.endswith("e") and not v.endswith("ee") else v) + "ing")
            for v in lemmas}


VERBS: dict[str, dict[str, tuple[str, str]]] = {
    "benchmark": _forms("carry", "push", "hold", "crawl", "climb", "descend"),
    "everyday": {**_forms("lug", "tote", "cart", "shove", "heave", "drive", "tiptoe", "steady", "inch",
                        "creep", "mount"),
                 "lug": ("lugs", "lugging"), "tiptoe": ("tiptoes", "tiptoeing")},
    "colloquial": {**_forms("muscle", "wobble", "totter", "scuttle", "clatter"), "schlep": ("schleps", "schlepping")},
}
WORDS: dict[str, str] = {"box": "NOUN", "body": "NOUN", "heavy": "ADJ", "carefully": "ADV",
                         "spread": "VERB",
                         "fours": "NOUN", "flight": "NOUN", "downstairs": "ADV",
                         "upstairs": "ADV", "some": "DET"}
PLURALS: dict[str, str] = {"sides": "side", "stairs": "stair"}
ENDS_DOWN: frozenset[str] = frozenset()
STARTS_DOWN: frozenset[str] = frozenset()
