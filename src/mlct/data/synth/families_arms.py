"""Arm, gesture and sports families of benchmark version 4: throwing and swinging (a ball, a
golf club, a baseball bat, a tennis racket), a hand held to the mouth or the ear (drinking, a
phone call), repeated paths of the hands (wiping a window, arm circles, directing traffic,
beckoning, dribbling), and whole-body moves led by the arms (looking around, a jump shot,
swaying to music, pulling a rope, tai chi).

Its interface (PARAMS, CLIPS, PHRASES, VERBS, WORDS, PLURALS, ENDS_DOWN, STARTS_DOWN) is
described at actions.VERSION_4_MODULES, which merges it.

The swings are right-handed (golf, baseball) or of the named hand; their timing follows what
people do: a throw's whip or a forehand takes 0.15-0.3 s, a golf downswing 0.3 s, tai chi moves
at well under 1 m/s. The clips start and end standing with the arms hanging.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from mlct.data.synth.motions import (Clip, Style, _arm, _frames, bump, ease, hanging_wrist, hold,
                                     neutral)
from mlct.data.synth.phrases_more import Phrase, Rng, _hands, _pick, _table
from mlct.data.synth.rig import Rig

# ---------------------------------------------------------------------------- helpers
# Wrist targets are in the chest frame relative to the shoulder (rig.pose_positions): x to the
# body's left, y up, z forward, metres; `sign` is +1 for the left arm and -1 for the right.
# Points "P" are in the chest frame relative to the midpoint between the shoulders.


def _sign(side: str) -> float:
    return 1.0 if side == "left" else -1.0


def _keys(t: np.ndarray, times: list[float], values: list) -> np.ndarray:
    """Eased piecewise interpolation through key poses: values[k] at times[k], held before the
    first and after the last; (n,) or (n, d) as the values are scalars or vectors."""
    times_a = np.asarray(times, dtype=float)
    v = np.asarray(values, dtype=float)
    k = np.clip(np.searchsorted(times_a, t, side="right") - 1, 0, len(times_a) - 2)
    u = ease((t - times_a[k]) / (times_a[k + 1] - times_a[k]))
    if v.ndim > 1:
        u = u[:, None]
    return v[k] + u * (v[k + 1] - v[k])


def _to_shoulder(point: np.ndarray, sign: float, style: Style) -> np.ndarray:
    """A point relative to the shoulders' midpoint as a wrist target of the arm of `sign`."""
    return point - np.array([sign * style.shoulder_x, 0.0, 0.0])


def _grip(clip: Clip, style: Style, point: np.ndarray, spread: np.ndarray,
          pole_l: np.ndarray, pole_r: np.ndarray) -> None:
    """Both hands on one handle (a club, a bat): the wrists at `point` -+ spread / 2, the left
    one at point + spread / 2."""
    _arm(clip, "left", _to_shoulder(point + spread / 2, 1.0, style), np.ones(clip.n), pole_l)
    _arm(clip, "right", _to_shoulder(point - spread / 2, -1.0, style), np.ones(clip.n), pole_r)


def _knees(ch: dict[str, np.ndarray], depth: np.ndarray, sides: str = "lr") -> None:
    """A soft-kneed athletic stance of `depth` (0..1: up to 0.25 rad at the hips, 0.45 at the
    knees), the feet flat."""
    for s in sides:
        ch[f"hip_flex_{s}"] = ch[f"hip_flex_{s}"] + 0.25 * depth
        ch[f"knee_{s}"] = ch[f"knee_{s}"] + 0.45 * depth
        ch[f"ankle_{s}"] = ch[f"ankle_{s}"] + 0.2 * depth


# ---------------------------------------------------------------------------- throws and swings

def throw(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """An overhand throw: the other foot steps forward while the throwing hand winds up
    behind the head, the chest turned away; the arm whips over the shoulder and follows
    through down across the body; about 2.4 s in all, the whip itself 0.15 s."""
    sign, k = _sign(hand), 1.0 / style.tempo
    n, t = _frames(2.5 * k + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    a = style.amplitude
    # Key times: still, wound up, cocked (hold), release, follow-through, recovered.
    times = [0.15, 0.15 + 0.7 * k, 0.15 + 0.95 * k, 0.15 + 1.1 * k, 0.15 + 1.4 * k,
             0.15 + 2.2 * k]
    hang = hanging_wrist(style, sign)
    wrist = _keys(t, times, [hang, [sign * 0.14, 0.16, -0.28], [sign * 0.12, 0.2, -0.32],
                             [-sign * 0.02, 0.14, 0.44], [-sign * 0.32, -0.42, 0.26], hang])
    pole = _keys(t, times, [[0.3 * sign, 0, -1], [sign, 0.1, -0.3], [sign, 0.2, -0.2],
                            [sign, -0.3, 0.2], [sign * 0.5, -1, 0], [0.3 * sign, 0, -1]])
    _arm(clip, hand, wrist, np.ones(n), pole)
    other, so = ("right", -1.0) if hand == "left" else ("left", 1.0)
    rest = hanging_wrist(style, so)
    off = _keys(t, times, [rest, [-so * 0.04, -0.02, 0.45], [-so * 0.04, 0.0, 0.45],
                           [so * 0.12, -0.3, 0.1], [so * 0.1, -0.42, 0.0], rest])
    _arm(clip, other, off, np.ones(n), np.array([so, -1.0, -0.2]))
    ch["spine_twist"] = a * _keys(t, times, [0, sign * 0.45, sign * 0.5, -sign * 0.3,
                                             -sign * 0.45, 0])
    ch["spine_bend"] = _keys(t, times, [0, -0.08, -0.1, 0.2, 0.32, 0])
    # The opposite foot steps out in front and plants before the whip; it comes back after.
    front, back = ("r", "l") if hand == "left" else ("l", "r")
    step = _keys(t, times, [0, 1, 1, 1, 1, 0])
    lift = bump((t - times[0]) / (0.7 * k)) + bump((t - times[4] - 0.1 * k) / (0.7 * k))
    ch[f"hip_flex_{front}"] = 0.3 * a * step + 0.25 * lift
    ch[f"knee_{front}"] = 0.15 * step + 0.5 * lift
    ch[f"ankle_{front}"] = -0.15 * step + 0.25 * lift
    ch[f"hip_flex_{back}"] = -0.2 * a * step
    ch[f"ankle_{back}"] = -0.2 * step
    return clip


def golf_swing(rig: Rig, fps: float, style: Style) -> Clip:
    """A right-handed golf swing: addresses the ball bent forward at the hips with soft knees,
    both hands together on the club hanging low; takes it back and up over the right shoulder
    as the chest turns away, swings down through the ball in 0.3 s and on up to a high finish
    over the left shoulder, the chest facing the target; then back to standing."""
    k = 1.0 / style.tempo
    n, t = _frames(4.4 * k + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    a = style.amplitude
    times = [0.1, 0.1 + 0.8 * k, 0.1 + 1.3 * k, 0.1 + 2.3 * k, 0.1 + 2.4 * k, 0.1 + 2.7 * k,
             0.1 + 2.95 * k, 0.1 + 3.5 * k, 0.1 + 4.3 * k]
    # standing, addressing, address held, top of the backswing, (pause), impact, finish, finish
    # held, standing
    address = np.array([0.0, -0.42, 0.2])
    top = np.array([-0.26, 0.16, 0.12])  # over the right shoulder, the left arm across the chest
    impact = np.array([0.02, -0.42, 0.2])
    finish = np.array([0.3, 0.12, -0.04])
    stand = np.array([0.0, -0.42, 0.18])
    point = _keys(t, times, [stand, address, address, top, top, impact, finish, finish, stand])
    _grip(clip, style, point, np.array([0.0, 0.05, 0.0]), np.array([0.3, -1.0, 0.0]),
          np.array([-0.3, -1.0, 0.0]))
    grip = _keys(t, times, [0, 1, 1, 1, 1, 1, 1, 1, 0])[:, None]
    for s, sign in (("l", 1.0), ("r", -1.0)):  # from and back to the hanging arms
        ch[f"wrist_{s}"] = grip * ch[f"wrist_{s}"] + (1 - grip) * hanging_wrist(style, sign)
    ch["spine_twist"] = a * _keys(t, times, [0, 0, 0, -0.85, -0.85, -0.05, 0.9, 0.9, 0])
    ch["spine_bend"] = _keys(t, times, [0, 0.5, 0.5, 0.45, 0.45, 0.5, 0.15, 0.12, 0])
    ch["head_nod"] = _keys(t, times, [0, 0.3, 0.3, 0.3, 0.3, 0.3, -0.1, -0.1, 0])
    _knees(ch, _keys(t, times, [0, 1, 1, 1, 1, 1, 0.5, 0.5, 0]))
    return clip


def bat_swing(rig: Rig, fps: float, style: Style) -> Clip:
    """A right-handed baseball swing: a batting stance with the hands together by the right
    shoulder, a short stride with the left foot, then the bat comes round level at chest
    height from the right side across the front to the left in 0.3 s, the chest turning with
    it, and wraps up over the left shoulder; then back to standing."""
    k = 1.0 / style.tempo
    n, t = _frames(4.0 * k + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    a = style.amplitude
    times = [0.1, 0.1 + 0.8 * k, 0.1 + 1.4 * k, 0.1 + 1.6 * k, 0.1 + 1.75 * k, 0.1 + 1.9 * k,
             0.1 + 2.2 * k, 0.1 + 2.8 * k, 0.1 + 3.8 * k]
    # standing, stance, loaded, (swing) right side, front, left side, wrapped, held, standing
    stand = np.array([0.0, -0.42, 0.18])
    stance = np.array([-0.22, 0.0, 0.08])
    loaded = np.array([-0.26, 0.02, 0.02])
    right = np.array([-0.28, -0.16, 0.3])
    front = np.array([0.0, -0.2, 0.44])
    left = np.array([0.34, -0.16, 0.22])
    wrapped = np.array([0.28, 0.04, -0.06])
    point = _keys(t, times, [stand, stance, loaded, right, front, left, wrapped, wrapped, stand])
    _grip(clip, style, point, np.array([0.0, 0.06, 0.0]), np.array([0.2, -1.0, -0.2]),
          np.array([-0.6, -0.4, -0.2]))
    grip = _keys(t, times, [0, 1, 1, 1, 1, 1, 1, 1, 0])[:, None]
    for s, sign in (("l", 1.0), ("r", -1.0)):
        ch[f"wrist_{s}"] = grip * ch[f"wrist_{s}"] + (1 - grip) * hanging_wrist(style, sign)
    ch["spine_twist"] = a * _keys(t, times, [0, -0.3, -0.4, -0.2, 0.2, 0.6, 0.75, 0.75, 0])
    ch["spine_bend"] = _keys(t, times, [0, 0.12, 0.12, 0.12, 0.1, 0.1, 0.05, 0.05, 0])
    _knees(ch, _keys(t, times, [0, 1, 1, 1, 0.8, 0.6, 0.5, 0.5, 0]))
    # The stride: the left foot lifts while loading and plants just before the swing.
    lift = bump((t - times[1]) / (times[3] - times[1]))
    ch["hip_flex_l"] = ch["hip_flex_l"] + 0.3 * lift
    ch["knee_l"] = ch["knee_l"] + 0.5 * lift
    ch["ankle_l"] = ch["ankle_l"] + 0.2 * lift
    return clip


def tennis_swing(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """A tennis forehand with the named hand: from the ready position (both hands on the racket
    in front, knees soft) the racket hand takes it back to its own side at waist height as the
    chest turns that way, the other hand out in front; it swings forward low to high across the
    body in 0.3 s to finish over the other shoulder; then back to standing."""
    sign, k = _sign(hand), 1.0 / style.tempo
    n, t = _frames(3.6 * k + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    a = style.amplitude
    other, so = ("right", -1.0) if hand == "left" else ("left", 1.0)
    times = [0.1, 0.1 + 0.7 * k, 0.1 + 1.0 * k, 0.1 + 1.7 * k, 0.1 + 1.85 * k, 0.1 + 2.05 * k,
             0.1 + 2.5 * k, 0.1 + 3.4 * k]
    # standing, ready, ready held, back, (swing) contact in front, finish, held, standing
    ready = np.array([sign * 0.05, -0.34, 0.3])
    own = [hanging_wrist(style, sign), _to_shoulder(ready, sign, style),
           _to_shoulder(ready, sign, style),
           [sign * 0.42, -0.3, -0.22], [sign * 0.05, -0.26, 0.45],
           [-sign * 0.24, 0.02, 0.28], [-sign * 0.3, 0.08, 0.12], hanging_wrist(style, sign)]
    _arm(clip, hand, _keys(t, times, own), np.ones(n),
         _keys(t, times, [[0.3 * sign, 0, -1], [sign, -1, 0], [sign, -1, 0], [0.5 * sign, -1, 0],
                          [sign * 0.6, -1, -0.2], [sign * 0.4, -0.5, 0.5], [sign, 0, 0.3],
                          [0.3 * sign, 0, -1]]))
    free = [hanging_wrist(style, so), _to_shoulder(ready + [so * 0.06, 0.02, 0.0], so, style),
            _to_shoulder(ready + [so * 0.06, 0.02, 0.0], so, style), [-so * 0.12, -0.1, 0.42],
            [so * 0.1, -0.25, 0.25], [so * 0.12, -0.35, 0.12], [so * 0.08, -0.4, 0.06],
            hanging_wrist(style, so)]
    _arm(clip, other, _keys(t, times, free), np.ones(n), np.array([so, -1.0, -0.2]))
    ch["spine_twist"] = a * _keys(t, times, [0, 0, 0, sign * 0.6, sign * 0.1, -sign * 0.45,
                                             -sign * 0.5, 0])
    ch["spine_bend"] = _keys(t, times, [0, 0.15, 0.15, 0.15, 0.12, 0.08, 0.05, 0])
    _knees(ch, _keys(t, times, [0, 1, 1, 1.2, 0.8, 0.5, 0.4, 0]))
    return clip


# ---------------------------------------------------------------------------- hand to the head

def drink(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Drinks from a cup in the named hand: lifts it to the mouth (the elbow down, the wrist
    just below and in front of the chin), tips the head back for a sip of about 1.2 s, lowers
    the cup to the waist and the arm back down."""
    sign, k = _sign(hand), 1.0 / style.tempo
    n, t = _frames(3.6 * k + 0.3, fps)
    clip = neutral(n, style)
    times = [0.15, 0.15 + 0.5 * k, 0.15 + 1.05 * k, 0.15 + 2.25 * k, 0.15 + 2.8 * k,
             0.15 + 3.5 * k]
    # hanging, cup at the waist, at the mouth, sip done, back at the waist, hanging
    waist = [-sign * 0.06, -0.3, 0.3]
    mouth = [-sign * (style.shoulder_x - 0.03), 0.06, 0.16]
    tipped = [-sign * (style.shoulder_x - 0.03), 0.1, 0.14]
    rest = hanging_wrist(style, sign)
    wrist = _keys(t, times, [rest, waist, mouth, tipped, waist, rest])
    _arm(clip, hand, wrist, np.ones(n), np.array([sign * 0.4, -1.0, 0.0]))
    clip.channels["head_nod"] = _keys(t, times, [0, 0, -0.1, -0.3, 0, 0])
    return clip


def phone_call(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Talks on the phone: the named hand holds it to the ear (the wrist beside the jaw, the
    elbow down and forward) for about 3 s, the head tipped a little towards it; the other arm
    hangs."""
    sign, k = _sign(hand), 1.0 / style.tempo
    n, t = _frames(4.3 * k + 0.3, fps)
    clip = neutral(n, style)
    times = [0.15, 0.15 + 0.7 * k, 0.15 + 3.6 * k, 0.15 + 4.2 * k]
    ear = np.array([-sign * (style.shoulder_x - 0.1), 0.07, 0.05])
    rest = hanging_wrist(style, sign)
    wrist = _keys(t, times, [rest, ear, ear + [0, 0.01, 0.01], rest])
    pole = np.array([sign * 0.3, -1.0, 0.5])
    _arm(clip, hand, wrist, np.ones(n), pole)
    on = _keys(t, times, [0, 1, 1, 0])
    clip.channels["spine_side"] = sign * 0.04 * on
    clip.channels["head_nod"] = 0.08 * on + 0.04 * np.sin(2 * np.pi * 0.8 * t) * on
    return clip


# ---------------------------------------------------------------------------- circles and waves

def wash_window(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Wipes a window with the named hand: the hand at shoulder height, most of an arm's length
    in front, makes four circles 0.25-0.3 m across in the frontal plane, about 0.9 s each."""
    sign, k = _sign(hand), 1.0 / style.tempo
    period = 0.9 * k
    n, t = _frames(1.2 + 4 * period + 0.2, fps)
    clip = neutral(n, style)
    up = hold(t - 0.1, 0.5, 4 * period + 0.1, 0.5)
    radius = 0.14 * style.amplitude
    phase = 2 * np.pi * np.clip(t - 0.6, 0, 4 * period) / period
    # Round the circle from its top, the hand going outwards first.
    wrist = np.stack([-sign * 0.06 + sign * radius * np.sin(phase), radius * np.cos(phase),
                      np.full(n, 0.4)], -1) - [0.0, radius, 0.0]
    _arm(clip, hand, wrist, up, np.array([sign, -1.0, -0.3]))
    clip.channels["spine_side"] = -sign * 0.03 * np.sin(phase) * up
    return clip


def arm_circles(rig: Rig, fps: float, style: Style) -> Clip:
    """Warm-up arm circles: both arms straight out at the sides at shoulder height make six
    small forward circles (about 0.25 m across, 0.7 s each)."""
    period = 0.7 / style.tempo
    n, t = _frames(1.3 + 6 * period + 0.2, fps)
    clip = neutral(n, style)
    up = hold(t - 0.1, 0.6, 6 * period + 0.1, 0.6)
    radius = 0.12 * style.amplitude
    phase = 2 * np.pi * np.clip(t - 0.7, 0, 6 * period) / period
    for side, sign in (("left", 1.0), ("right", -1.0)):
        wrist = np.stack([np.full(n, sign * 0.48), radius * np.sin(phase),
                          0.05 + radius * (np.cos(phase) - 1)], -1)
        _arm(clip, side, wrist, up, np.array([0.0, -0.3, -1.0]))
    return clip


def beckon(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Beckons with the named hand: the forearm held out in front at waist height, palm up,
    curls up towards the chest and back four times (about 0.6 s each), the elbow at the side."""
    sign, period = _sign(hand), 0.6 / style.tempo
    n, t = _frames(1.2 + 4 * period + 0.2, fps)
    clip = neutral(n, style)
    up = hold(t - 0.1, 0.5, 4 * period + 0.1, 0.5)
    curl = 0.5 - 0.5 * np.cos(2 * np.pi * np.clip(t - 0.6, 0, 4 * period) / period)
    out = np.array([-sign * 0.02, -0.3, 0.36])
    curled = np.array([-sign * 0.02, -0.1, 0.16])
    wrist = out + curl[:, None] * (curled - out) * style.amplitude
    _arm(clip, hand, wrist, up, np.array([sign * 0.3, -1.0, -0.4]))
    return clip


def direct_traffic(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Directs traffic: the other arm held straight out to its side at shoulder height (stop),
    the named arm waves the cars on, sweeping from out at its side to across the front at
    shoulder height four times (about 0.8 s each); the chest turns a little with it."""
    sign, period = _sign(hand), 0.8 / style.tempo
    n, t = _frames(1.3 + 4 * period + 0.2, fps)
    clip = neutral(n, style)
    up = hold(t - 0.1, 0.6, 4 * period + 0.1, 0.6)
    other, so = ("right", -1.0) if hand == "left" else ("left", 1.0)
    _arm(clip, other, np.array([so * 0.49, 0.02, 0.08]), up, np.array([0.0, -1.0, -0.5]))
    sweep = 0.5 - 0.5 * np.cos(2 * np.pi * np.clip(t - 0.7, 0, 4 * period) / period)
    angle = (0.2 + 1.25 * sweep * style.amplitude)  # radians from the side towards the front
    reach = 0.47
    wrist = np.stack([sign * reach * np.cos(angle) - sign * 0.1 * np.sin(angle),
                      np.full(n, 0.0), reach * np.sin(angle)], -1)
    _arm(clip, hand, wrist, up, np.array([0.0, -1.0, -0.3]))
    clip.channels["spine_twist"] = -sign * 0.1 * sweep * up
    return clip


def look_around(rig: Rig, fps: float, style: Style) -> Clip:
    """Looks around: the head and upper body turn to the left, then to the right, about 35
    degrees each way and held a moment, the feet and hips staying put, then back to the front."""
    k = 1.0 / style.tempo
    n, t = _frames(4.6 * k + 0.3, fps)
    clip = neutral(n, style)
    times = [0.15, 0.15 + 0.8 * k, 0.15 + 1.5 * k, 0.15 + 2.8 * k, 0.15 + 3.5 * k,
             0.15 + 4.4 * k]
    turn = 0.6 * style.amplitude
    clip.channels["spine_twist"] = _keys(t, times, [0, turn, turn, -turn, -turn, 0])
    clip.channels["head_nod"] = _keys(t, times, [0, -0.05, -0.05, -0.05, -0.05, 0])
    return clip


def dribble(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Dribbles a basketball standing in place: knees bent and the body leaning a little
    forward, the named hand pats down on the ball at hip height beside the front of the body
    seven times (about 0.45 s a bounce), the other arm out for balance."""
    sign, period = _sign(hand), 0.45 / style.tempo
    n, t = _frames(1.2 + 7 * period + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    on = hold(t - 0.1, 0.5, 7 * period + 0.1, 0.5)
    _knees(ch, on)
    ch["spine_bend"] = 0.2 * on
    # The hand meets the ball at the top of its bounce and pushes it down.
    pat = 0.5 - 0.5 * np.cos(2 * np.pi * np.clip(t - 0.6, 0, 7 * period) / period)
    wrist = np.stack([np.full(n, sign * 0.1), -0.36 - 0.12 * style.amplitude * pat,
                      np.full(n, 0.26)], -1)
    _arm(clip, hand, wrist, on, np.array([sign, -0.3, -0.6]))
    other, so = ("right", -1.0) if hand == "left" else ("left", 1.0)
    _arm(clip, other, np.array([so * 0.2, -0.38, 0.18]), on, np.array([so, -1.0, -0.3]))
    return clip


def shoot_basketball(rig: Rig, fps: float, style: Style) -> Clip:
    """A jump shot: the ball in both hands at the chest, a dip of the knees, a small jump
    (about 8 cm, 0.3 s up) as both hands push up over the head and release; land softly."""
    k = 1.0 / style.tempo
    n, t = _frames(3.0 * k + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    take_off, fly = 0.15 + 1.3 * k, 0.3
    times = [0.15, 0.15 + 0.7 * k, 0.15 + 1.1 * k, take_off + 0.2, take_off + fly + 0.15,
             take_off + fly + 1.0 * k]
    # hanging, ball at the chest, dipped, hands up (release), still up after landing, hanging
    chest = np.array([0.0, -0.2, 0.3])
    above = np.array([0.0, 0.42, 0.2])
    ball = _keys(t, times, [chest, chest, chest + [0, -0.04, 0], above, above, above])
    weight = _keys(t, times, [0, 1, 1, 1, 1, 0])
    for side, sign in (("left", 1.0), ("right", -1.0)):
        wrist = _to_shoulder(ball + [sign * 0.1, 0.0, 0.0], sign, style)
        _arm(clip, side, wrist, weight, np.array([sign * 0.6, -1.0, -0.2]))
    dip = hold(t - times[1], 0.4 * k, 0.1, 0.15) * (t < take_off)
    dip += hold(t - take_off - fly, 0.06, 0.05, 0.3) * (t >= take_off + fly)
    for s in "lr":
        ch[f"hip_flex_{s}"] = 0.45 * dip
        ch[f"knee_{s}"] = 0.8 * dip
        ch[f"ankle_{s}"] = 0.35 * dip
    ch["spine_bend"] = 0.1 * dip
    airborne = (t >= take_off) & (t < take_off + fly)
    progress = np.clip((t - take_off) / fly, 0, 1)
    clip.clearance = np.where(airborne, 0.08 * style.amplitude * np.sin(np.pi * progress), 0.0)
    clip.flight = airborne
    clip.flight_velocity[airborne] = [0.0, 0.0]
    for s in "lr":
        ch[f"ankle_{s}"] = ch[f"ankle_{s}"] - 0.3 * airborne * np.sin(np.pi * progress)
    return clip


def sway(rig: Rig, fps: float, style: Style) -> Clip:
    """Sways to music: the hips shift from side to side over planted feet, the upper body
    leaning the other way, four sways at about 0.6 Hz; the arms hang loose."""
    period = 1.7 / style.tempo
    n, t = _frames(0.8 + 4 * period + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    on = hold(t - 0.1, 0.6, 4 * period - 0.4, 0.6)
    wave = np.sin(2 * np.pi * np.clip(t - 0.3, 0, None) / period) * on
    shift = 0.07 * style.amplitude * wave  # both legs tilt: the pelvis goes 6-8 cm sideways
    ch["hip_abd_l"], ch["hip_abd_r"] = shift, -shift
    ch["spine_side"] = 0.12 * style.amplitude * wave
    ch["head_nod"] = 0.05 * np.abs(wave)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        wrist = hanging_wrist(style, sign) + np.stack(
            [np.zeros(n), np.zeros(n), 0.05 * wave * sign], -1)
        _arm(clip, side, wrist, on)
    return clip


def pull_rope(rig: Rig, fps: float, style: Style) -> Clip:
    """Pulls on a rope hand over hand: leaning back with the knees bent, each hand in turn
    reaches forward at chest height and pulls back to the chest, four pulls a hand (about
    1 s each)."""
    period = 1.0 / style.tempo
    n, t = _frames(1.4 + 4 * period + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    on = hold(t - 0.1, 0.7, 4 * period + 0.1, 0.7)
    _knees(ch, 1.2 * on)
    ch["spine_bend"] = -0.3 * style.amplitude * on
    ch["hip_flex_l"] = ch["hip_flex_l"] + 0.15 * on  # the hips sit back behind the feet
    ch["hip_flex_r"] = ch["hip_flex_r"] + 0.15 * on
    phase = 2 * np.pi * np.clip(t - 0.8, 0, None) / period
    for side, sign, offset in (("left", 1.0, 0.0), ("right", -1.0, np.pi)):
        reach = 0.5 - 0.5 * np.cos(phase + offset)  # 1 = out in front, 0 = at the chest
        wrist = _to_shoulder(np.array([sign * 0.04, -0.22, 0.14]), sign, style) \
            + reach[:, None] * np.array([-sign * 0.0, 0.06, 0.34])
        _arm(clip, side, wrist, on, np.array([sign, -1.0, -0.5]))
    return clip


def tai_chi(rig: Rig, fps: float, style: Style) -> Clip:
    """Tai chi: slow and smooth on bent knees; the weight shifts forward and the palms push out
    at chest height, shifts back as they circle out to the sides and in, twice (about 3.2 s a
    round)."""
    period = 3.2 / style.tempo
    n, t = _frames(1.6 + 2 * period + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    on = hold(t - 0.1, 1.0, 2 * period - 0.2, 1.0)
    phase = 2 * np.pi * np.clip(t - 0.8, 0, 2 * period) / period
    push = (0.5 - 0.5 * np.cos(phase)) * on  # 1 = palms pushed out, weight forward
    _knees(ch, 1.5 * on)
    ch["spine_bend"] = ch["spine_bend"] + 0.05 * on
    ch["spine_twist"] = 0.1 * np.sin(phase) * on
    # Weight shift: the front hip flexes and the back hip extends a little as the body goes in.
    ch["hip_flex_l"] = ch["hip_flex_l"] + 0.06 * push
    ch["hip_flex_r"] = ch["hip_flex_r"] - 0.06 * push
    for side, sign in (("left", 1.0), ("right", -1.0)):
        opened = np.sin(phase / 2) ** 2 * (1 - push)  # out to the sides on the way back
        near = _to_shoulder(np.array([sign * 0.16, -0.2, 0.2]), sign, style)
        far = _to_shoulder(np.array([sign * 0.14, -0.1, 0.46]), sign, style)
        wrist = near + push[:, None] * (far - near) \
            + opened[:, None] * np.array([sign * 0.22, 0.05, -0.05])
        _arm(clip, side, wrist, on, np.array([sign, -1.0, -0.3]))
    return clip


CLIPS: dict[str, Callable[..., Clip]] = {
    "throw": throw, "golf_swing": golf_swing, "bat_swing": bat_swing,
    "tennis_swing": tennis_swing, "drink": drink, "phone_call": phone_call,
    "wash_window": wash_window, "arm_circles": arm_circles, "look_around": look_around,
    "direct_traffic": direct_traffic, "beckon": beckon, "dribble": dribble,
    "shoot_basketball": shoot_basketball, "sway": sway, "pull_rope": pull_rope,
    "tai_chi": tai_chi}
_HAND = {"hand": ("left", "right")}
PARAMS: dict[str, dict[str, tuple]] = {
    family: (dict(_HAND) if family in ("throw", "tennis_swing", "drink", "phone_call",
                                       "wash_window", "direct_traffic", "beckon", "dribble")
             else {})
    for family in CLIPS}


# ---------------------------------------------------------------------------- captions
# The rules of phrases_more.py: a side in the benchmark's words and never the other one, not
# even of the idle arm.

def _sided(*options: str) -> Phrase:
    """Phrases of a one-handed family: `{h}` is the hand, said as phrases_more says it."""
    return lambda p, rng: _pick(rng, options).format(h=_hands(p["hand"], rng))


BENCHMARK: dict[str, Phrase] = {
    **_table(
        golf_swing=("<swing> a golf club", "<take> a full golf swing",
                    "<swing> a golf club back and through", "<hit> a golf ball",
                    "<bend> over a golf ball and <swing> the club"),
        bat_swing=("<swing> a baseball bat", "<swing> a bat with both hands",
                   "<take> a swing with a baseball bat", "<step> in and <swing> a baseball bat",
                   "<swing> a bat level across HIS chest"),
        arm_circles=("<do> arm circles", "<circle> both arms out at HIS sides",
                     "<make> small circles with both arms held out",
                     "<hold> both arms out and <circle> them"),
        look_around=("<look> around", "<look> to the left and to the right",
                     "<look> back over each shoulder", "<look> around HIS body"),
        shoot_basketball=("<shoot> a basketball", "<jump> and <shoot> a basketball",
                          "<take> a jump shot", "<shoot> a ball with both hands over HIS head"),
        sway=("<sway> to music", "<sway> from side to side", "<sway> HIS hips to the music",
              "<sway> side to side to a song"),
        pull_rope=("<pull> on a rope", "<pull> a rope hand over hand",
                   "<lean> back and <pull> a rope toward HIS chest",
                   "<pull> something in on a rope"),
        tai_chi=("<do> tai chi", "<practice> tai chi", "<move> slowly through tai chi",
                 "<perform> slow tai chi movements"),
    ),
    "throw": _sided("<throw> a ball overhand with {h}", "<throw> a ball with {h}",
                    "<wind> up and <throw> a ball with {h}", "<make> an overhand throw with {h}",
                    "<throw> something overhand with {h}"),
    "tennis_swing": _sided("<swing> a tennis racket with {h}", "<hit> a forehand with {h}",
                           "<play> a tennis forehand with {h}",
                           "<swing> a racket forward with {h}"),
    "drink": _sided("<drink> from a cup in {h}", "<raise> a cup to HIS mouth with {h} and <drink>",
                    "<take> a drink with {h}", "<lift> a glass to HIS mouth with {h}"),
    "phone_call": _sided("<talk> on the phone, holding it with {h}",
                         "<hold> a phone to HIS ear with {h}", "<talk> on a phone in {h}",
                         "<answer> the phone with {h}"),
    "wash_window": _sided("<wash> a window with {h}", "<wipe> a window in circles with {h}",
                          "<clean> a window in front of HIS body with {h}",
                          "<wash> the windows with {h}"),
    "direct_traffic": _sided("<direct> traffic, waving cars on with {h}",
                             "<direct> traffic with {h}",
                             "<hold> out the other arm and <wave> traffic on with {h}",
                             "<signal> cars forward with {h}"),
    "beckon": _sided("<beckon> with {h}", "<beckon> someone over with {h}",
                     "<wave> someone closer with {h}", "<call> someone over with {h}"),
    "dribble": _sided("<dribble> a basketball with {h}", "<bounce> a ball with {h}",
                      "<dribble> a ball in place with {h}"),
}


EVERYDAY: dict[str, Phrase] = {
    **_table(
        golf_swing=("<tee> off with a golf club", "<drive> a golf ball down the course",
                    "<practice> HIS golf swing"),
        bat_swing=("<hit> a baseball with a bat", "<take> a cut with a baseball bat",
                   "<bat> at an imaginary pitch"),
        arm_circles=("<warm> up with arm circles", "<loosen> up HIS shoulders with arm circles",
                     "<roll> both arms in small circles"),
        look_around=("<glance> around", "<scan> the surroundings",
                     "<check> both sides, twisting at the waist"),
        shoot_basketball=("<jump> and <launch> a basketball toward the hoop",
                          "<shoot> a ball at the basket", "<fire> off a jump shot"),
        sway=("<move> gently from side to side to music", "<rock> side to side to a tune",
              "<groove> slowly to the music"),
        pull_rope=("<tug> on a rope hand over hand", "<heave> on a rope, leaning back",
                   "<drag> something in with a rope"),
        tai_chi=("<flow> through slow tai chi moves", "<go> through a slow tai chi routine",
                 "<practice> slow, flowing tai chi"),
    ),
    "throw": _sided("<toss> a ball overarm with {h}", "<hurl> a ball forward with {h}",
                    "<fling> a ball with {h}"),
    "tennis_swing": _sided("<return> a tennis ball with a forehand, racket in {h}",
                           "<strike> a tennis ball with {h}",
                           "<hit> a forehand shot holding the racket in {h}"),
    "drink": _sided("<sip> from a glass held in {h}", "<bring> a cup to HIS lips with {h}",
                    "<take> a sip from a cup in {h}"),
    "phone_call": _sided("<chat> on the phone held in {h}",
                         "<make> a phone call, the phone in {h}",
                         "<press> a phone to HIS ear with {h}"),
    "wash_window": _sided("<scrub> a window in circles with {h}",
                          "<polish> the glass in front with {h}",
                          "<clean> the windows with {h}"),
    "direct_traffic": _sided("<guide> traffic, waving cars through with {h}",
                             "<signal> the cars to go with {h}",
                             "<wave> the traffic on with {h}, the other arm out"),
    "beckon": _sided("<motion> someone to come closer with {h}",
                     "<gesture> to someone to come over with {h}",
                     "<call> someone in with {h}"),
    "dribble": _sided("<bounce> a basketball with {h}", "<pat> a ball down again and again "
                      "with {h}", "<keep> a basketball bouncing with {h}"),
}


COLLOQUIAL: dict[str, Phrase] = {
    **_table(
        golf_swing=("<tee> off", "<whack> a golf ball", "<smack> a drive down the fairway"),
        bat_swing=("<swing> for the fences", "<take> a big cut at the ball",
                   "<knock> a baseball out of the park"),
        arm_circles=("<windmill> both arms in little circles",
                     "<limber> up with some arm circles"),
        look_around=("<rubberneck> at the scene", "<crane> HIS neck to check both ways",
                     "<take> a good look about"),
        shoot_basketball=("<sink> a jumper", "<pop> a jump shot", "<shoot> hoops"),
        sway=("<groove> to the music", "<bop> side to side to the tunes",
              "<vibe> to the beat, swaying"),
        pull_rope=("<heave> on a rope like a tug of war", "<haul> away on a rope"),
        tai_chi=("<do> some slow motion tai chi", "<flow> through tai chi in the park"),
    ),
    "throw": _sided("<chuck> a ball with {h}", "<whip> a ball overhand with {h}",
                    "<pitch> a ball with {h}"),
    "tennis_swing": _sided("<smack> a forehand with {h}", "<rip> a forehand with {h}"),
    "drink": _sided("<swig> from a cup in {h}", "<knock> back a drink with {h}"),
    "phone_call": _sided("<yak> on the phone held in {h}", "<gab> on the phone, {h} at HIS ear"),
    "wash_window": _sided("<give> the window a wipe with {h}",
                          "<scrub> away at a window with {h}"),
    "direct_traffic": _sided("<wave> the cars on like a traffic cop with {h}",
                             "<play> traffic cop, waving with {h}"),
    "beckon": _sided("<wave> someone over with {h}", "<give> a come here wave with {h}"),
    "dribble": _sided("<dribble> the rock with {h}",
                      "<bounce> the ball like a point guard with {h}"),
}


def _s_sided(family: str, *bare: str) -> Phrase:
    """The bare phrase for the right hand, the benchmark's words (which name it) for the left."""
    def phrase(p: dict, rng: Rng) -> str:
        return BENCHMARK[family](p, rng) if p["hand"] == "left" else _pick(rng, bare)
    return phrase


SHORT: dict[str, Phrase] = {
    **_table(
        golf_swing=("<swing> a golf club", "<swing> a club"),
        bat_swing=("<swing> a bat", "<swing> a baseball bat"),
        arm_circles=("<do> arm circles", "<circle> HIS arms"),
        look_around=("<look> around", "<look> around"),
        shoot_basketball=("<shoot> a basketball", "<shoot> a ball"),
        sway=("<sway>", "<sway>", "<sway> to music"),
        pull_rope=("<pull> a rope", "<pull> on a rope"),
        tai_chi=("<do> tai chi", "<do> tai chi"),
    ),
    "throw": _s_sided("throw", "<throw> a ball", "<throw>"),
    "tennis_swing": _s_sided("tennis_swing", "<swing> a racket", "<hit> a forehand"),
    "drink": _s_sided("drink", "<drink>", "<drink> something"),
    "phone_call": _s_sided("phone_call", "<talk> on the phone", "<talk> on the phone"),
    "wash_window": _s_sided("wash_window", "<wash> a window", "<wipe> a window"),
    "direct_traffic": _s_sided("direct_traffic", "<direct> traffic", "<direct> traffic"),
    "beckon": _s_sided("beckon", "<beckon>", "<beckon>"),
    "dribble": _s_sided("dribble", "<dribble> a ball", "<dribble>"),
}
PHRASES: dict[str, dict[str, Phrase]] = {"benchmark": BENCHMARK, "everyday": EVERYDAY,
                                         "colloquial": COLLOQUIAL, "short": SHORT}

VERBS: dict[str, dict[str, tuple[str, str]]] = {
    "benchmark": {
        "answer": ("answers", "answering"), "beckon": ("beckons", "beckoning"),
        "bounce": ("bounces", "bouncing"), "call": ("calls", "calling"),
        "clean": ("cleans", "cleaning"), "direct": ("directs", "directing"),
        "dribble": ("dribbles", "dribbling"), "drink": ("drinks", "drinking"),
        "hit": ("hits", "hitting"), "look": ("looks", "looking"), "play": ("plays", "playing"),
        "practice": ("practices", "practicing"), "pull": ("pulls", "pulling"),
        "shoot": ("shoots", "shooting"), "signal": ("signals", "signaling"),
        "sway": ("sways", "swaying"), "swing": ("swings", "swinging"),
        "talk": ("talks", "talking"), "wash": ("washes", "washing"),
        "wind": ("winds", "winding"), "wipe": ("wipes", "wiping")},
    "everyday": {
        "bat": ("bats", "batting"), "chat": ("chats", "chatting"),
        "check": ("checks", "checking"), "drag": ("drags", "dragging"),
        "fling": ("flings", "flinging"), "flow": ("flows", "flowing"),
        "gesture": ("gestures", "gesturing"), "glance": ("glances", "glancing"),
        "groove": ("grooves", "grooving"), "guide": ("guides", "guiding"),
        "hurl": ("hurls", "hurling"), "launch": ("launches", "launching"),
        "motion": ("motions", "motioning"), "pat": ("pats", "patting"),
        "polish": ("polishes", "polishing"), "press": ("presses", "pressing"),
        "return": ("returns", "returning"), "rock": ("rocks", "rocking"),
        "scan": ("scans", "scanning"), "scrub": ("scrubs", "scrubbing"),
        "roll": ("rolls", "rolling"), "twist": ("twists", "twisting"),
        "sip": ("sips", "sipping"), "tee": ("tees", "teeing"), "toss": ("tosses", "tossing"),
        "tug": ("tugs", "tugging")},
    "colloquial": {
        "bop": ("bops", "bopping"), "chuck": ("chucks", "chucking"),
        "crane": ("cranes", "craning"), "gab": ("gabs", "gabbing"),
        "pitch": ("pitches", "pitching"), "pop": ("pops", "popping"),
        "rip": ("rips", "ripping"), "rubberneck": ("rubbernecks", "rubbernecking"),
        "smack": ("smacks", "smacking"), "swig": ("swigs", "swigging"),
        "vibe": ("vibes", "vibing"), "whack": ("whacks", "whacking"),
        "whip": ("whips", "whipping"), "windmill": ("windmills", "windmilling"),
        "yak": ("yaks", "yakking")},
}
WORDS: dict[str, str] = {
    **dict.fromkeys("ball baseball basketball bat club cup drink ear forehand glass golf mouth "
                    "movement music phone racket rope shot song swing tai chi tennis throw "
                    "traffic window car".split(), "NOUN"),
    "overhand": "ADV", "closer": "ADV", "small": "ADJ", "level": "ADJ", "through": "ADP",
    "them": "PRON", "it": "PRON", "toward": "ADP", "held": "VERB", "look": "VERB", "each": "DET"}
PLURALS: dict[str, str] = {"cars": "car", "windows": "window", "shoulders": "shoulder",
                           "movements": "movement"}
ENDS_DOWN: frozenset[str] = frozenset()
STARTS_DOWN: frozenset[str] = frozenset()
