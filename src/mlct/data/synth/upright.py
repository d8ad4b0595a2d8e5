"""Exercises and held gestures done standing in place (benchmark version 3): jumping jacks,
marching in place, lunges, standing on one leg, pointing, saluting, hands on the hips, crossed arms,
nodding.

Wrist targets are in the chest frame relative to the shoulder (rig.pose_positions): x to the
body's left, y up, z forward, metres; `sign` is +1 for the left arm and -1 for the right.
"""

from __future__ import annotations

import numpy as np

from mlct.data.synth.motions import Clip, Style, _arm, _frames, bump, hold, neutral
from mlct.data.synth.rig import Rig


def jumping_jack(rig: Rig, fps: float, style: Style, count: int) -> Clip:
    """`count` jumping jacks: hop out to land with the feet apart and the arms overhead, hop
    back in with the arms down; about 1.1 s a jack."""
    period = 1.1 / style.tempo
    n, t = _frames(0.4 + count * period + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    fly = 0.2  # seconds in the air on each hop, 4-6 cm up
    opened = np.zeros(n)
    for k in range(count):
        t0 = 0.3 + k * period
        for hop_start in (t0, t0 + period / 2):
            airborne = (t >= hop_start) & (t < hop_start + fly)
            progress = np.clip((t - hop_start) / fly, 0, 1)
            clip.clearance = np.where(airborne, 0.05 * np.sin(np.pi * progress), clip.clearance)
            clip.flight |= airborne
            clip.flight_velocity[airborne] = [0.0, 0.0]
        # Open during the first hop, held while landed apart, closed during the second hop.
        opened += hold(t - t0, fly, period / 2 - fly, fly)
    opened = np.clip(opened, 0, 1)
    spring = sum((bump((t - 0.3 - k * period / 2 - fly) / 0.25) for k in range(2 * count)),
                 np.zeros(n))  # a small knee bend at each landing
    for s in "lr":
        ch[f"hip_abd_{s}"] = 0.28 * style.amplitude * opened
        ch[f"hip_flex_{s}"] = 0.12 * spring
        ch[f"knee_{s}"] = 0.3 * spring
        ch[f"ankle_{s}"] = 0.18 * spring
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # The arms sweep out sideways and up in an arc, not forward.
        angle = np.pi * 0.92 * opened  # from hanging to overhead, in the body's side plane
        length = 0.95 * style.arm_length
        wrist = np.stack([sign * (0.03 + length * np.sin(angle)), -length * np.cos(angle),
                          np.full(n, 0.03)], -1)
        _arm(clip, side, wrist, np.ones(n), np.array([sign * 0.2, 0.0, -1.0]))
    return clip


def march_in_place(rig: Rig, fps: float, style: Style) -> Clip:
    """Marches on the spot: each knee in turn lifts to hip height, the opposite arm swings."""
    step = 0.55 / style.tempo  # seconds per step; 3 steps a leg
    n, t = _frames(6 * step + 0.6, fps)
    clip = neutral(n, style)
    ch = clip.channels
    env = hold(t - 0.2, 0.3, 6 * step - 0.3, 0.3)
    for s, offset in (("l", 0.0), ("r", step)):
        lift = sum((bump((t - 0.25 - offset - 2 * k * step) / step) for k in range(3)),
                   np.zeros(n))
        ch[f"hip_flex_{s}"] = 1.05 * style.amplitude * lift
        ch[f"knee_{s}"] = 1.45 * lift
        ch[f"ankle_{s}"] = 0.2 * lift
    phase = np.pi * np.clip(t - 0.25, 0, None) / step
    for side, sign in (("left", 1.0), ("right", -1.0)):
        swing = 0.28 * np.sin(phase) * (-sign)  # the left arm forward with the right knee
        wrist = np.stack([np.full(n, 0.05 * sign), -0.28 - 0.1 * np.abs(np.sin(phase)),
                          0.12 + swing], -1)
        _arm(clip, side, wrist, env, np.array([0.2 * sign, 0.0, -1.0]))
    return clip


def one_leg_stand(rig: Rig, fps: float, style: Style, leg: str) -> Clip:
    """Stands on the named leg, the other foot held up beside the knee, arms out to balance."""
    n, t = _frames(3.6 / style.tempo + 0.6, fps)
    clip = neutral(n, style)
    ch = clip.channels
    free = "r" if leg == "left" else "l"
    up = hold(t - 0.2, 0.6, n / fps - 1.6, 0.6)
    ch[f"hip_flex_{free}"] = 0.75 * up
    ch[f"knee_{free}"] = 1.4 * up
    ch[f"ankle_{free}"] = -0.2 * up
    ch["spine_side"] = (0.05 if leg == "left" else -0.05) * up  # the weight over the standing foot
    ch["spine_side"] += 0.02 * np.sin(2 * np.pi * 0.7 * t) * up  # small corrections
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, np.array([sign * 0.42, -0.25, 0.08]), up, np.array([0.0, -1.0, -0.3]))
    return clip


def _hold_gesture(fps: float, style: Style, seconds: float) -> tuple[Clip, np.ndarray]:
    """A neutral clip and the weight of a gesture raised over 0.6 s, held, lowered."""
    n, t = _frames(seconds / style.tempo + 1.5, fps)
    return neutral(n, style), hold(t - 0.15, 0.6, n / fps - 1.5, 0.6)


def point(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Points ahead with the named arm straight out at shoulder height, held."""
    clip, up = _hold_gesture(fps, style, 2.0)
    sign = 1.0 if hand == "left" else -1.0
    wrist = np.array([-0.08 * sign, 0.02, 0.97 * style.arm_length])
    _arm(clip, hand, wrist, up, np.array([sign, -1.0, 0.0]))
    clip.channels["spine_twist"] = -sign * 0.08 * up  # the shoulder leads a little
    return clip


def salute(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """A military salute: the named hand's fingertips to the brow, the elbow out to the side."""
    clip, up = _hold_gesture(fps, style, 1.8)
    sign = 1.0 if hand == "left" else -1.0
    wrist = np.array([-sign * (style.shoulder_x - 0.02), 0.2, 0.12])
    _arm(clip, hand, wrist, up, np.array([sign, 0.3, 0.2]))
    return clip


def hands_on_hips(rig: Rig, fps: float, style: Style) -> Clip:
    """Both hands on the hips, the elbows out to the sides, held."""
    clip, up = _hold_gesture(fps, style, 2.2)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # On the crest of the hip bone, a hand's width above the hip joints.
        wrist = np.array([-sign * 0.04, -0.4, -0.02])
        _arm(clip, side, wrist, up, np.array([sign, 0.0, -0.4]))
    return clip


def cross_arms(rig: Rig, fps: float, style: Style) -> Clip:
    """Folds the arms across the chest, each hand at the other elbow, held."""
    clip, up = _hold_gesture(fps, style, 2.2)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # The left forearm lies over the right one, a hand's breadth higher.
        wrist = np.array([-sign * (style.shoulder_x + 0.12), -0.27 + (0.04 if side == "left"
                                                                       else 0.0), 0.2])
        _arm(clip, side, wrist, up, np.array([sign, -1.0, -0.2]))
    return clip


def nod(rig: Rig, fps: float, style: Style, count: int) -> Clip:
    """Nods `count` times: the head tips forward and back, the body still."""
    period = 0.6 / style.tempo
    n, t = _frames(0.6 + count * period + 0.6, fps)
    clip = neutral(n, style)
    clip.channels["head_nod"] = 0.45 * style.amplitude * sum(
        (bump((t - 0.5 - k * period) / period) for k in range(count)), np.zeros(n))
    return clip



def lunge(rig: Rig, fps: float, style: Style, leg: str, count: int) -> Clip:
    """`count` forward lunges with the named leg: step it forward, sink until the back knee is
    near the floor (front shin upright, back heel up), push back up and step back; 2.2 s each."""
    period = 2.2 / style.tempo
    n, t = _frames(0.3 + count * period + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    front, back = leg[0], ("r" if leg == "left" else "l")
    split, depth, lift = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(count):
        u = (t - 0.3 - k * period) / period
        split += hold(u, 0.22, 0.56, 0.22)
        depth += hold(u - 0.24, 0.2, 0.12, 0.2)
        lift += bump(u / 0.22) + bump((u - 0.78) / 0.22)  # the stepping foot clears the floor
    amp = style.amplitude ** 0.5
    hip_f = (0.6 * split + 0.75 * depth) * amp
    knee_f = 1.35 * depth * amp + 0.8 * lift
    ch[f"hip_flex_{front}"] = hip_f + 0.3 * lift
    ch[f"knee_{front}"] = knee_f
    ch[f"ankle_{front}"] = (knee_f - hip_f) * (1 - lift) + 0.2 * lift  # flat once down
    hip_b = (-0.45 * split + 0.3 * depth) * amp
    knee_b = 1.3 * depth * amp
    ch[f"hip_flex_{back}"] = hip_b
    ch[f"knee_{back}"] = knee_b
    ch[f"ankle_{back}"] = knee_b - hip_b - (0.35 * split + 0.5 * depth)  # the heel up
    ch["spine_bend"] = 0.08 * depth
    for side, sign in (("left", 1.0), ("right", -1.0)):  # hands on the hips for balance
        _arm(clip, side, np.array([-sign * 0.04, -0.4, -0.02]), np.clip(split * 1.5, 0, 1),
             np.array([sign, 0.0, -0.4]))
    return clip


UPRIGHT_CLIPS = {"jumping_jack": jumping_jack, "march_in_place": march_in_place,
                 "one_leg_stand": one_leg_stand, "point": point, "salute": salute,
                 "hands_on_hips": hands_on_hips, "cross_arms": cross_arms, "nod": nod,
                 "lunge": lunge}
