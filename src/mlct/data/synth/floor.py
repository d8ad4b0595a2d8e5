"""Floor transitions and reaching down (benchmark version 3): lie down, get up, sit on the floor,
pick something up, touch the toes, push-ups.

A person lies down the way most adults do without their hands' help: squat, sit back onto the
buttocks, roll back onto the back while the legs slide out, about 2.5 s in all. The whole body
tips about the pelvis (the rig's body_pitch channel) and the seat, back, head and hands may bear
weight (the floor channel: compose.place_on_ground puts each through its flesh on the floor
and holds the seat still while the legs slide). Getting up is the same path run backwards.
Angles in radians, times in seconds (divided by the style's tempo), distances in metres.
"""

from __future__ import annotations

import numpy as np

from mlct.data.synth.motions import Clip, Style, _arm, _frames, ease, hold, neutral
from mlct.data.synth.rig import SIDES, Rig, pose_positions, rot_x

SUPINE = -np.pi / 2  # body_pitch of lying on the back
# The deep squat the floor transitions pass through (feet flat: ankle = knee - hip + pitch).
SQUAT_HIP, SQUAT_KNEE, SQUAT_LEAN = 1.75, 2.25, 0.45
SIT_BACK = -0.9  # body_pitch once sat back onto the buttocks, knees up
SIT_LEAN = 0.7  # spine bend then: the chest over the knees, the torso 0.2 rad behind vertical


def _lowering(t: np.ndarray, tempo: float) -> tuple[np.ndarray, np.ndarray]:
    """(squat, sit back) weights, 0 -> 1: down into a squat, then back onto the buttocks."""
    squat = ease(t / (0.9 / tempo))
    sit = ease((t - 0.7 / tempo) / (0.8 / tempo))
    return squat, sit


def _squat_and_sit(clip: Clip, squat: np.ndarray, sit: np.ndarray, out: np.ndarray,
                   pitch_out: float, hip_out: float, lean_out: float) -> None:
    """Channels of squatting (weight `squat`), sitting back (`sit`), then going over to a pose
    with the legs out straight (`out`: body_pitch pitch_out, hip flexion hip_out, spine bend
    lean_out)."""
    ch = clip.channels
    pitch = SIT_BACK * sit * (1 - out) + pitch_out * out
    hip = SQUAT_HIP * squat * (1 - out) + hip_out * out
    knee = SQUAT_KNEE * squat * (1 - out)
    for s in "lr":
        ch[f"hip_flex_{s}"] = hip
        ch[f"knee_{s}"] = knee
        # Feet flat on the floor while they bear weight; toes up once the legs lie out straight.
        ch[f"ankle_{s}"] = (knee - hip + pitch) * (1 - out) + 0.1 * out
    ch["body_pitch"] = pitch
    ch["spine_bend"] = (SQUAT_LEAN * squat + (SIT_LEAN - SQUAT_LEAN) * sit) * (1 - out) \
        + lean_out * out
    ch["head_nod"] = 0.25 * sit * (1 - out)  # looking at the knees, not the sky, while sitting
    # The seat, back and hands bear weight once down in the squat (standing, the heels' flesh
    # would lift the toes off the floor).
    ch["floor"] = (squat > 0.5).astype(float)


def lie_down(rig: Rig, fps: float, style: Style) -> Clip:
    """From standing to lying on the back: squat, sit back, roll down as the legs slide out."""
    tempo = style.tempo / 1.15  # 2.5-3.4 s from standing to the head on the floor
    n, t = _frames(2.7 / tempo + 0.4, fps)
    clip = neutral(n, style)
    squat, sit = _lowering(t, tempo)
    down = ease((t - 1.35 / tempo) / (1.35 / tempo))
    _squat_and_sit(clip, squat, sit, down, SUPINE, 0.0, 0.0)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # Forward for balance in the squat, down beside the hips to sit, then along the body
        # on the floor (behind the chest's plane, which is down once lying).
        forward = np.array([0.05 * sign, -0.35, 0.35])
        beside = np.array([0.14 * sign, -0.88 * style.arm_length, -0.07])
        reach = np.clip(squat - sit, 0, 1)[:, None]
        wrist = (1 - reach) * beside + reach * forward
        # The elbows bend outwards, not into the floor.
        _arm(clip, side, wrist, np.clip(squat, 0, 1), np.array([sign, 0.0, -0.3]))
    return clip


def get_up(rig: Rig, fps: float, style: Style) -> Clip:
    """From lying on the back to standing: lying down played backwards (sit up, pull the feet
    in, rise out of the squat), as people who get up without their hands do."""
    clip = lie_down(rig, fps, style)
    return Clip({name: values[::-1].copy() for name, values in clip.channels.items()},
                clip.clearance[::-1].copy(), clip.flight[::-1].copy(),
                clip.flight_velocity[::-1].copy())


def sit_floor(rig: Rig, fps: float, style: Style) -> Clip:
    """Sits down on the floor: squat, sit back, stretch the legs out, lean back on the hands."""
    tempo = style.tempo
    n, t = _frames(2.4 / tempo + 1.2, fps)
    clip = neutral(n, style)
    squat, sit = _lowering(t, tempo)
    out = ease((t - 1.3 / tempo) / (1.0 / tempo))
    # Sitting with the legs out: the torso 0.2 rad behind vertical, the legs along the floor.
    _squat_and_sit(clip, squat, sit, out, -0.6, 0.95, 0.1)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # The palms on the floor a little behind the hips, the arms straight.
        behind = _reach_target(rig, clip, n - 1, side, -0.18, 0.04, from_pelvis=True)
        _arm(clip, side, behind, np.clip(sit, 0, 1), np.array([0.3 * sign, 0.0, 1.0]))
    return clip


def _chest_frame(pose: dict[str, np.ndarray], frame: int) -> np.ndarray:
    """(3, 3) rotation of the chest at `frame` (yaw left out: targets are in the body frame)."""
    return (rot_x(pose["body_pitch"][frame:frame + 1])
            @ rot_x(pose["spine_bend"][frame:frame + 1]))[0]


def _reach_target(rig: Rig, clip: Clip, frame: int, side: str, ahead: float, above: float,
                  from_pelvis: bool = False) -> np.ndarray:
    """The wrist target (chest frame, metres from the shoulder) that puts the wrist `above` m
    over the floor and `ahead` m in front of the ankles (or the pelvis) at `frame`, in the pose
    of that frame."""
    pose = {name: values[frame:frame + 1] for name, values in clip.channels.items()}
    body = pose_positions(rig, pose)[0] / rig.scale
    if clip.channels["floor"][frame]:
        joints, flesh = zip(*rig.floor_points.items())
        floor = (body[list(joints), 1] - np.array(flesh)).min()
    else:
        floor = body[list(rig.contact_points), 1].min()
    origin = body[0] if from_pelvis else 0.5 * (body[rig.ankle["left"]] + body[rig.ankle["right"]])
    shoulder = body[rig.shoulder[side]]
    goal = np.array([shoulder[0] * 0.8, floor + above, origin[2] + ahead])
    return _chest_frame(clip.channels, frame).T @ (goal - shoulder)


def pick_up(rig: Rig, fps: float, style: Style, hand: str) -> Clip:
    """Squats and leans to reach the floor in front of the feet with one or both hands, then
    stands up holding the thing in front of the belly."""
    tempo = style.tempo
    down, stay, up = 0.9 / tempo, 0.4, 0.9 / tempo
    n, t = _frames(down + stay + up + 0.9, fps)
    clip = neutral(n, style)
    ch = clip.channels
    depth = hold(t - 0.1, down, stay, up)
    pitch = 0.5 * depth  # the pelvis tips forward with the lean
    for s in "lr":
        ch[f"hip_flex_{s}"] = SQUAT_HIP * depth + pitch
        ch[f"knee_{s}"] = SQUAT_KNEE * depth
        ch[f"ankle_{s}"] = ch[f"knee_{s}"] - ch[f"hip_flex_{s}"] + pitch  # feet flat
    ch["body_pitch"] = pitch
    ch["spine_bend"] = 0.8 * depth
    ch["head_nod"] = 0.3 * depth
    bottom = int(np.argmax(depth))
    hands = SIDES if hand == "both" else (hand,)
    for side in SIDES:
        sign = 1.0 if side == "left" else -1.0
        if side not in hands:  # the free hand rests on the knee
            _arm(clip, side, np.array([0.05 * sign, -0.4, 0.3]), depth)
            continue
        low = _reach_target(rig, clip, bottom, side, 0.25, 0.06)
        if hand == "both":  # hands either side of the thing, a box's width apart
            low = low + np.array([-sign * 0.08, 0.0, 0.0])
        carry = np.array([-sign * (0.1 if hand == "both" else 0.0) + 0.02 * sign, -0.32, 0.3])
        after = ease((t - 0.1 - down - stay) / up)[:, None]
        wrist = (1 - after) * low + after * carry
        reach = np.clip(ease((t - 0.1) / down), 0, 1)
        _arm(clip, side, wrist, reach, np.array([sign, -0.5, -0.3]))
    return clip


def touch_toes(rig: Rig, fps: float, style: Style) -> Clip:
    """Bends forward from the hips with straight legs until the hands touch the toes, holds,
    comes back up."""
    tempo = style.tempo
    down, stay, up = 1.1 / tempo, 0.8, 1.1 / tempo
    n, t = _frames(down + stay + up + 0.4, fps)
    clip = neutral(n, style)
    ch = clip.channels
    depth = hold(t - 0.2, down, stay, up)
    pitch = 1.6 * depth
    for s in "lr":
        ch[f"hip_flex_{s}"] = pitch  # the legs stay upright while the pelvis tips forward
        ch[f"knee_{s}"] = 0.08 * depth
        ch[f"ankle_{s}"] = 0.08 * depth
    ch["body_pitch"] = pitch
    ch["spine_bend"] = 1.0 * depth
    ch["head_nod"] = 0.2 * depth
    bottom = int(np.argmax(depth))
    for side in SIDES:
        sign = 1.0 if side == "left" else -1.0
        toes = _reach_target(rig, clip, bottom, side, 0.12, 0.08)
        _arm(clip, side, np.tile(toes, (n, 1)), depth, np.array([sign, 0.0, -1.0]))
    return clip


def _plank(rig: Rig, pitch: np.ndarray) -> dict[str, np.ndarray]:
    """Pose channels of a straight body tipped forward by `pitch` (T,), arms at rest."""
    clip = neutral(len(pitch), Style(arm_length=rig.arm_length, shoulder_x=rig.shoulder_x))
    clip.channels["body_pitch"] = pitch
    return clip.channels


def _hands_on_floor(rig: Rig, clip: Clip, plank: np.ndarray, top: float,
                    ahead: float) -> dict[str, np.ndarray]:
    """Wrist targets (chest frame) that keep both hands on the floor: `ahead` m in front of the
    ankles in the squat, and in the plank (weight `plank`) where they stay put relative to the
    toes, under the shoulders of the plank at body_pitch `top`. Planted hands grip the floor
    (compose.SEAT_GRIP), so the feet jump back and forth behind them."""
    body = pose_positions(rig, clip.channels) / rig.scale  # the arms' own pose does not matter
    legs = [j for j in rig.floor_points if j not in (*rig.wrist.values(), *rig.elbow.values())]
    flesh = np.array([rig.floor_points[j] for j in legs])
    floor = (body[:, legs, 1] - flesh).min(axis=1)
    toes = [j for side in SIDES for j in rig.foot[side]]
    ankles = 0.5 * (body[:, rig.ankle["left"]] + body[:, rig.ankle["right"]])
    at_top = pose_positions(rig, _plank(rig, np.array([top])))[0] / rig.scale
    chest = rot_x(clip.channels["body_pitch"]) @ rot_x(clip.channels["spine_bend"])
    targets = {}
    for side in SIDES:
        reach = at_top[rig.shoulder[side], 2] - at_top[toes, 2].mean()  # hands from the toes
        z = (1 - plank) * (ankles[:, 2] + ahead) + plank * (body[:, toes, 2].mean(axis=1) + reach)
        shoulder = body[:, rig.shoulder[side]]
        hand = np.stack([shoulder[:, 0], floor + rig.floor_points[rig.wrist[side]], z], -1)
        targets[side] = np.einsum("tji,tj->ti", chest, hand - shoulder)  # into the chest frame
    return targets


PLANK_TOP = 1.28  # body_pitch with straight arms: the shoulders an arm's length over the hands
PLANK_BOTTOM = 1.5  # the chest joint 0.2 m over the floor: the chest a hand's breadth up


def push_up(rig: Rig, fps: float, style: Style, count: int) -> Clip:
    """Squats, puts the hands on the floor and steps back into a plank, does `count` push-ups
    (the body straight, pivoting on the toes, hands planted), steps the feet in and stands."""
    tempo = style.tempo
    squat, jump, period = 0.8 / tempo, 0.6 / tempo, 1.3 / tempo  # down, feet back, one push-up
    n, t = _frames(2 * (squat + jump) + count * period + 0.2, fps)
    clip = neutral(n, style)
    ch = clip.channels
    # Squat with the hands to the floor, then the feet back; the same the other way at the end.
    crouch = hold(t, squat, 2 * jump + count * period, squat)
    plank = hold(t - squat, jump, count * period, jump)
    start = squat + jump
    dips = sum((np.sin(np.pi * np.clip((t - start - k * period) / period, 0, 1)) ** 2
                for k in range(count)), np.zeros(n))
    pitch_plank = PLANK_TOP + (PLANK_BOTTOM - PLANK_TOP) * dips
    squat_pitch = 0.75  # far enough over the feet for the hands to reach the floor
    # Jumping back, the torso tips onto the hands first and the knees stay tucked while the
    # feet pass under the body (the hands bear the weight), then the legs stretch out.
    tip = np.clip(plank * 1.8, 0, 1)
    tuck = np.sin(np.pi * plank) * 0.9
    for s in "lr":
        squat_hip, squat_knee = SQUAT_HIP + squat_pitch, SQUAT_KNEE
        ch[f"hip_flex_{s}"] = squat_hip * (1 - plank) * crouch + 0.6 * tuck
        ch[f"knee_{s}"] = (squat_knee * (1 - plank) + tuck) * crouch
        ch[f"ankle_{s}"] = (squat_knee - squat_hip + squat_pitch) * crouch * (1 - plank)
    ch["body_pitch"] = squat_pitch * crouch * (1 - tip) + pitch_plank * tip
    ch["spine_bend"] = 0.8 * crouch * (1 - plank)
    ch["head_nod"] = -0.2 * plank  # looking at the floor ahead, not at the feet
    ch["floor"] = (crouch > 0.5).astype(float)
    hands = _hands_on_floor(rig, clip, plank, PLANK_TOP, 0.3)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # The elbows bend back along the body, as in a close-grip push-up.
        _arm(clip, side, hands[side], np.clip(crouch, 0, 1), np.array([0.4 * sign, 1.0, 0.0]))
    return clip
