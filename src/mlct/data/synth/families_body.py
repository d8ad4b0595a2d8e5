"""Whole-body families of benchmark version 4: crawling, stairs, falls, carrying and pushing,
uneven and balancing walks, jumps.

Its interface (PARAMS, CLIPS, PHRASES, VERBS, WORDS, PLURALS, ENDS_DOWN, STARTS_DOWN) is
described at actions.VERSION_4_MODULES, which merges it.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from mlct.data.synth.motions import (Clip, Style, _arm, _frames, bump, concatenate, ease, gait,
                                    hip_wave, hold, neutral)
from mlct.data.synth.phrases_more import Phrase, Rng, _count, _pick, _table, _times
from mlct.data.synth.rig import SIDES, Rig, pose_positions, rot_x

# ------------------------------------------------------------------- walks with the arms busy
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
    settle = 0.04 * hold(t - 0.1, 0.3, n / fps - 0.8, 0.3)
    pelvis = np.stack([np.zeros(n), _smooth(low, fps, 0.1) - settle,
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


# -------------------------------------------------------------------- stepping over, falling

def _swing_window(t: np.ndarray, style: Style, kind: str, offset: float,
                  after: float) -> np.ndarray:
    """0 -> 1 over the first swing of a gait's leg (phase `offset`: left 0, right 0.5) that
    starts after `after` s, 0 elsewhere (the gait of motions.gait with this style)."""
    from mlct.data.synth.motions import _GAITS

    freq, duty = _GAITS[kind][0] * style.tempo, _GAITS[kind][5]
    u = np.mod(freq * t + offset, 1.0)
    swinging = u > duty
    starts = np.flatnonzero(swinging[1:] & ~swinging[:-1]) + 1
    first = starts[t[starts] > after][0]
    end = first + int(np.argmax(~swinging[first:]))
    window = np.zeros(len(t))
    window[first:end] = np.linspace(0, 1, end - first, endpoint=False)
    return window


def step_over(rig: Rig, fps: float, style: Style, leg: str) -> Clip:
    """Walks forward and steps over something knee-high: the named leg lifts high over it
    (the knee up to the hip), then the other follows, the foot tucked up behind."""
    clip = gait(fps, style, "slow", strides=3 + style.tempo)
    ch = clip.channels
    t = np.arange(clip.n) / fps
    lead, trail = leg[0], ("r" if leg == "left" else "l")
    offsets = {"l": 0.0, "r": 0.5}
    first = _swing_window(t, style, "slow", offsets[lead], 1.0)
    begun = t[np.argmax(first > 0)]
    second = _swing_window(t, style, "slow", offsets[trail], begun)
    for s, window, hip, knee in ((lead, first, 1.05, 1.0), (trail, second, 0.85, 1.35)):
        high = bump(window) * (window > 0)
        ch[f"hip_flex_{s}"] = ch[f"hip_flex_{s}"] + hip * style.amplitude * high
        ch[f"knee_{s}"] = ch[f"knee_{s}"] + knee * high
        ch[f"ankle_{s}"] = ch[f"ankle_{s}"] + 0.3 * high
    over = bump(np.clip((t - begun + 0.2) / 1.6, 0, 1))
    ch["spine_bend"] = ch["spine_bend"] + 0.1 * over  # watching the obstacle
    ch["head_nod"] = ch["head_nod"] + 0.25 * over
    for side, sign in (("left", 1.0), ("right", -1.0)):  # the arms out a little for balance
        _arm(clip, side, np.array([0.25 * sign, -0.4, 0.12]), over)
    return clip


def fall_forward(rig: Rig, fps: float, style: Style) -> Clip:
    """Trips and falls forward: the body pitches over the feet faster and faster, the hands
    shoot out to the floor, the knees buckle, and it lands on the front and lies there."""
    tempo = style.tempo
    n, t = _frames(0.3 + 1.1 / tempo + 1.4, fps)
    clip = neutral(n, style)
    ch = clip.channels
    trip = 0.25
    u = np.clip((t - trip) / (1.0 / tempo), 0, 1)
    tip = u ** 2 * (3 - 2 * u) ** 0.5 / 1.0  # speeding up as it goes over, then stopped
    tip = np.clip(tip, 0, 1)
    ch["body_pitch"] = (np.pi / 2 - 0.05) * tip
    buckle = bump(np.clip(u / 1.1, 0, 1))
    for s in "lr":
        ch[f"hip_flex_{s}"] = 0.35 * buckle
        ch[f"knee_{s}"] = 0.7 * buckle
        ch[f"ankle_{s}"] = -0.5 * tip  # the toes pointing back once lying
    ch["head_nod"] = -0.45 * tip  # the face kept off the floor
    ch["floor"] = (tip > 0.4).astype(float)
    zero = np.zeros(n)
    hands = _hands_down(rig, clip, {s: zero - 0.05 for s in SIDES}, {s: zero for s in SIDES})
    out = ease((t - trip) / 0.35)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # Out in front to break the fall, then flat beside the shoulders, the elbows bent out.
        ahead = np.array([0.1 * sign, 0.15, 0.45])
        reach = ease((u - 0.45) / 0.4)[:, None]
        wrist = (1 - reach) * ahead + reach * hands[side]
        _arm(clip, side, wrist, out, np.array([sign, 0.3, 0.0]))
    return clip


def fall_backward(rig: Rig, fps: float, style: Style) -> Clip:
    """Loses balance backwards: the knees give, the body drops onto the seat and rolls back
    onto the back in about a second, the arms flung out, and it lies there."""
    from mlct.data.synth.floor import SUPINE, _squat_and_sit

    tempo = style.tempo
    n, t = _frames(0.3 + 1.0 / tempo + 1.4, fps)
    clip = neutral(n, style)
    t0 = 0.25
    squat = ease((t - t0) / (0.35 / tempo))  # the knees buckle
    sit = ease((t - t0 - 0.15 / tempo) / (0.4 / tempo))  # down onto the seat
    down = ease((t - t0 - 0.45 / tempo) / (0.55 / tempo))  # back onto the floor
    _squat_and_sit(clip, squat * 0.7, sit, down, SUPINE, 0.35, 0.0)
    ch = clip.channels
    for s in "lr":  # the knees stay a little bent where the legs land
        ch[f"knee_{s}"] = ch[f"knee_{s}"] + 0.6 * down
        ch[f"hip_flex_{s}"] = ch[f"hip_flex_{s}"] + 0.0 * down
    ch["head_nod"] = ch["head_nod"] + 0.3 * down  # the chin tucked against the fall
    flung = ease((t - t0) / 0.3)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # Out to the sides and back, to catch the floor, then lying beside the body.
        out = np.array([sign * 0.45, -0.15, -0.1])
        side_down = np.array([sign * 0.4, -0.3, -0.05])
        lie = down[:, None]
        _arm(clip, side, (1 - lie) * out + lie * side_down, flung, np.array([0.0, -1.0, 0.0]))
    return clip


SIT_UP_HIP, SIT_UP_KNEE = 1.0, 1.9  # lying with the knees up, the feet flat by the seat
SIT_UP_RISE = 1.2  # body_pitch the trunk rises by: the chest up over the thighs


def sit_ups(rig: Rig, fps: float, style: Style, count: int) -> Clip:
    """Lying on the back with the knees bent and the hands behind the head, sits up `count`
    times, the chest coming up to the knees, and lies back down; the feet stay on the floor."""
    from mlct.data.synth.floor import SUPINE

    period = 1.6 / style.tempo
    n, t = _frames(0.3 + count * period + 0.4, fps)
    clip = neutral(n, style)
    ch = clip.channels
    rise = sum((hold(t - 0.3 - k * period, 0.6 * period / 1.2, 0.1 * period / 1.2,
                     0.5 * period / 1.2) for k in range(count)), np.zeros(n))
    pitch = SUPINE + SIT_UP_RISE * rise
    ch["body_pitch"] = pitch
    ch["spine_bend"] = 0.35 * rise  # the back curls up
    ch["head_nod"] = 0.3 + 0.1 * rise
    for s in "lr":  # the legs keep their place on the floor while the trunk pitches
        ch[f"hip_flex_{s}"] = SIT_UP_HIP + (pitch - SUPINE)
        ch[f"knee_{s}"] = np.full(n, SIT_UP_KNEE)
        ch[f"ankle_{s}"] = np.full(n, SIT_UP_KNEE - SIT_UP_HIP - np.pi / 2 + 0.2)
    ch["floor"] = np.ones(n)
    for side, sign in (("left", 1.0), ("right", -1.0)):  # the fingers laced behind the head
        _arm(clip, side, np.array([-sign * 0.1, 0.2, -0.1]), np.ones(n),
             np.array([sign, 0.2, -0.2]))
    return clip


# -------------------------------------------------------------- uneven walking, putting down

def _warp(clip: Clip, tau: np.ndarray, fps: float) -> Clip:
    """The clip played at times `tau` (T,) seconds instead of its own frame times."""
    t = np.arange(clip.n) / fps
    tau = np.clip(tau, 0, t[-1])

    def at(values: np.ndarray) -> np.ndarray:
        if values.ndim == 1:
            return np.interp(tau, t, values)
        return np.stack([np.interp(tau, t, values[:, k]) for k in range(values.shape[1])], -1)

    return Clip({name: at(values) for name, values in clip.channels.items()}, at(clip.clearance),
                at(clip.flight.astype(float)) > 0.5, at(clip.flight_velocity))


def limp(rig: Rig, fps: float, style: Style, side: str) -> Clip:
    """Walks forward favouring the named (hurt) leg: a short, quick step onto it with the knee
    held stiff and swung out, the trunk lurching over it, a longer stance on the good leg."""
    from mlct.data.synth.motions import _GAITS

    slow = replace(style, tempo=style.tempo * 0.85)
    clip = gait(fps, slow, "slow", strides=3 + style.tempo)
    ch = clip.channels
    t = np.arange(clip.n) / fps
    freq, duty = _GAITS["slow"][0] * slow.tempo, _GAITS["slow"][5]
    hurt = side[0]
    sign = 1.0 if side == "left" else -1.0
    phase = 0.0 if hurt == "l" else 0.5
    u = np.mod(freq * t + phase, 1.0)
    on_hurt = bump(np.clip(u / duty, 0, 1)) * (u < duty)  # the hurt leg bears the weight
    knee = ch[f"knee_{hurt}"]
    bend = knee / max(float(knee.max()), 1e-6)
    ch[f"knee_{hurt}"] = 0.45 * knee  # a stiff knee ...
    ch[f"hip_abd_{hurt}"] = ch[f"hip_abd_{hurt}"] + 0.16 * bend  # ... swung out to clear the floor
    ch[f"ankle_{hurt}"] = ch[f"ankle_{hurt}"] + 0.2 * bend  # the toes up
    env = ease(t / 0.6) * ease((t[-1] - t) / 0.6)
    ch["spine_side"] = ch["spine_side"] + sign * 0.14 * on_hurt * env  # the lurch over it
    # The hurt leg's stance hurried: the clip runs faster while it bears the weight.
    centre = duty / 2 - phase
    tau = t + 0.3 / (2 * np.pi * freq) * (np.sin(2 * np.pi * (freq * t - centre))
                                          - np.sin(-2 * np.pi * centre))
    return _warp(clip, tau, fps)


def put_down(rig: Rig, fps: float, style: Style) -> Clip:
    """Holding a box in front of the belly in both hands, squats and sets it on the floor in
    front of the feet, lets go and stands up empty-handed (picking it up, run backwards)."""
    from mlct.data.synth.floor import pick_up

    clip = pick_up(rig, fps, style, "both")
    return Clip({name: values[::-1].copy() for name, values in clip.channels.items()},
                clip.clearance[::-1].copy(), clip.flight[::-1].copy(),
                clip.flight_velocity[::-1].copy())


def stumble(rig: Rig, fps: float, style: Style) -> Clip:
    """Walking, trips: the trunk pitches forward, the arms fly out in front, two hurried
    catching steps, and it straightens up and walks on."""
    clip = gait(fps, style, "normal", strides=3.5 + style.tempo)
    ch = clip.channels
    t = np.arange(clip.n) / fps
    trip = 1.3 / style.tempo
    lurch = bump(np.clip((t - trip) / 1.0, 0, 1))  # the pitch forward and back up
    ch["spine_bend"] = ch["spine_bend"] + 0.85 * style.amplitude * lurch
    ch["head_nod"] = ch["head_nod"] - 0.3 * lurch  # the eyes stay on the way ahead
    for s in "lr":  # longer catching steps
        ch[f"hip_flex_{s}"] = ch[f"hip_flex_{s}"] * (1 + 0.35 * lurch)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, np.array([sign * 0.25, -0.05, 0.4]), np.clip(1.6 * lurch, 0, 1),
             np.array([sign, -1.0, 0.0]))
    # The steps hurry through the stumble: the walk played up to 1.6 times as fast.
    speed = 1 + 0.6 * bump(np.clip((t - trip + 0.1) / 0.9, 0, 1))
    tau = np.concatenate([[0.0], np.cumsum(speed[1:]) / fps])
    return _warp(clip, tau, fps)


def long_jump(rig: Rig, fps: float, style: Style) -> Clip:
    """A run-up of a few strides, a plant on both feet with a swing of the arms, a long
    two-footed jump forward (about 2 m, the knees tucked and the legs reaching forward), a deep
    landing with the arms forward, and standing up."""
    run = gait(fps, style, "run", strides=3.0)
    cut = int(round(2.3 / (1.40 * style.tempo) * fps))  # before the run's envelope eases out
    run = Clip({k: v[:cut].copy() for k, v in run.channels.items()}, run.clearance[:cut].copy(),
               run.flight[:cut].copy(), run.flight_velocity[:cut].copy())
    amp = style.amplitude
    crouch_t, fly, land_t = 0.3, 0.6, 1.3  # seconds: the plant, the flight, landing and rising
    n, t = _frames(crouch_t + fly + land_t, fps)
    jump = neutral(n, style)
    ch = jump.channels
    airborne = (t >= crouch_t) & (t < crouch_t + fly)
    progress = np.clip((t - crouch_t) / fly, 0, 1)
    jump.clearance = np.where(airborne, 0.4 * amp * np.sin(np.pi * progress), 0.0)
    jump.flight = airborne
    jump.flight_velocity[airborne] = [0.0, 2.1 * amp / (fly * fps)]  # about 2.1 m in the air
    plant = ease(t / 0.15) * (1 - ease((t - crouch_t + 0.05) / 0.1))
    landing = hold(t - crouch_t - fly, 0.12, 0.25, land_t - 0.6)
    depth = np.maximum(0.6 * plant, 0.9 * landing)
    reach = np.sin(np.pi * progress) * airborne + ease((progress - 0.5) / 0.5) * airborne
    for s in "lr":
        # Crouch with the feet flat; in the air the knees tuck, then the legs reach forward.
        ch[f"hip_flex_{s}"] = 1.2 * depth + 0.9 * reach
        ch[f"knee_{s}"] = 1.8 * depth + 1.0 * np.sin(np.pi * progress) * airborne
        ch[f"ankle_{s}"] = (1.8 - 1.2) * depth - 0.2 * airborne
    ch["spine_bend"] = 0.5 * depth + 0.3 * airborne
    for side, sign in (("left", 1.0), ("right", -1.0)):
        back = np.array([0.08 * sign, -0.8 * style.arm_length, -0.3])  # swung back on the plant
        up = np.array([0.1 * sign, 0.2, 0.4])  # thrown forward and up in the air
        ahead = np.array([0.1 * sign, -0.15, 0.45])  # forward on landing, for balance
        a = ease((t - crouch_t + 0.1) / 0.25)[:, None]
        b = ease((t - crouch_t - fly + 0.15) / 0.3)[:, None]
        wrist = (1 - a) * back + a * ((1 - b) * up + b * ahead)
        _arm(jump, side, wrist, np.maximum(plant, hold(t - crouch_t, 0.1, fly, land_t - 0.4)))
    return concatenate([run, jump], fps, 0.2)[0]


# ---------------------------------------------------------------------------- jumping rope

def jump_rope(rig: Rig, fps: float, style: Style, count: int) -> Clip:
    """Skips a rope `count` times in place: small two-footed hops on the balls of the feet,
    the wrists at hip height a little out to the sides, turning the rope in small circles."""
    period = 0.5 / style.tempo
    n, t = _frames(0.6 + count * period + 0.5, fps)
    clip = neutral(n, style)
    ch = clip.channels
    fly = 0.24 * period / 0.5  # seconds in the air a hop, 8-10 cm up
    spring = np.zeros(n)
    for k in range(count):
        t0 = 0.6 + k * period
        airborne = (t >= t0) & (t < t0 + fly)
        progress = np.clip((t - t0) / fly, 0, 1)
        clip.clearance = np.where(airborne, 0.09 * style.amplitude * np.sin(np.pi * progress),
                                  clip.clearance)
        clip.flight |= airborne
        clip.flight_velocity[airborne] = [0.0, 0.0]
        spring += bump((t - t0 - fly + 0.05) / (period - fly + 0.1))  # the knees give, landing
        ch["ankle_l"] = ch["ankle_l"] - 0.35 * airborne * np.sin(np.pi * progress)  # toes down
        ch["ankle_r"] = ch["ankle_l"]
    for s in "lr":
        ch[f"hip_flex_{s}"] = 0.12 * spring
        ch[f"knee_{s}"] = 0.25 * spring
        ch[f"ankle_{s}"] = ch[f"ankle_{s}"] + 0.13 * spring
    turning = hold(t - 0.1, 0.4, n / fps - 0.8, 0.4)
    angle = 2 * np.pi * np.clip(t - 0.6 + fly / 2, 0, None) / period  # a turn a hop
    for side, sign in (("left", 1.0), ("right", -1.0)):
        # Small circles of the hands beside the hips, the rope passing under the feet mid-air.
        wrist = np.stack([sign * (0.2 + 0.03 * np.cos(angle)), -0.45 + 0.05 * np.sin(angle),
                          0.12 + 0.05 * np.cos(angle)], -1)
        _arm(clip, side, wrist, turning, np.array([sign, -0.5, -1.0]))
    return clip


# ---------------------------------------------------------------------------- phrases
# The rules of phrases_more.py: a side is said in the benchmark's words and never the other side,
# a count always (short: never); <verb> marks and HIS as in text.py.

def _step_over(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<step> over an obstacle with HIS {s} leg first",
                       f"<walk> forward and <step> over something, leading with the {s} leg",
                       f"<walk> and <step> high over an obstacle with the {s} foot first",
                       f"<step> over something in HIS way, {s} leg first"))


def _limp(p: dict, rng: Rng) -> str:
    s = p["side"]
    return _pick(rng, (f"<limp> forward on an injured {s} leg", f"<limp> forward on HIS {s} leg",
                       f"<limp> along on a hurt {s} leg",
                       f"<walk> forward unevenly, sparing the {s} leg",
                       f"<limp> forward, favoring the {s} leg"))


def _jump_rope(p: dict, rng: Rng) -> str:
    n = p["count"]
    return _pick(rng, (f"<jump> rope {_times(n, rng)}", f"<skip> rope {_times(n, rng)}",
                       f"<do> {_count(n, rng)} small jumps over a rope",
                       f"<hop> over a jump rope {_times(n, rng)} on both feet"))


def _sit_ups(p: dict, rng: Rng) -> str:
    n = p["count"]
    return _pick(rng, (f"<do> {_count(n, rng)} situps", f"<perform> {_count(n, rng)} situps",
                       f"<lie> on HIS back and <do> {_count(n, rng)} situps",
                       f"<do> {_count(n, rng)} situps with HIS hands behind HIS head",
                       f"<sit> up from lying on HIS back {_times(n, rng)}"))


BENCHMARK: dict[str, Phrase] = {**_table(
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
    fall_forward=("<fall> forward onto the floor", "<trip> and <fall> forward",
                  "<trip> over something and <fall> flat on the ground",
                  "<stumble> and <fall> forward onto HIS hands", "<fall> down on HIS face"),
    fall_backward=("<fall> backward onto the floor", "<fall> over backward onto HIS back",
                   "<fall> back and <land> on HIS back", "<fall> down backward",
                   "<tip> over backward and <land> on the floor"),
    put_down=("<put> a box down on the floor", "<put> something down on the ground",
              "<bend> down and <put> a box on the floor",
              "<squat> and <place> something on the floor",
              "<set> a box down on the floor"),
    long_jump=("<do> a long jump", "<run> up and <do> a long jump",
               "<run> forward and <leap> far, landing on both feet",
               "<run> a few steps and <jump> forward a long way"),
    stumble=("<stumble> forward and <catch> HIS balance",
             "<trip> and <stumble> but <stay> on HIS feet", "<stumble> on the way and <recover>",
             "<trip> over something and <catch> HIS balance",
             "<walk> forward, <stumble> and <go> on walking"),
), "step_over": _step_over, "sit_ups": _sit_ups, "limp": _limp,
   "jump_rope": _jump_rope}


def _e_step_over(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<clear> an obstacle with a high step of the {s} leg",
                       f"<raise> the {s} knee high and <clear> something on the floor",
                       f"<stride> over a low barrier, {s} foot first"))


def _e_sit_ups(p: dict, rng: Rng) -> str:
    n = p["count"]
    return _pick(rng, (f"<crunch> up from the floor {_times(n, rng)}",
                       f"<curl> up off HIS back {_times(n, rng)}",
                       f"<work> HIS abs with {_count(n, rng)} sit-ups"))


def _e_limp(p: dict, rng: Rng) -> str:
    s = p["side"]
    return _pick(rng, (f"<hobble> forward on a sore {s} leg",
                       f"<hobble> along, keeping the weight off the {s} leg",
                       f"<shuffle> forward, nursing a bad {s} knee"))


def _c_limp(p: dict, rng: Rng) -> str:
    s = p["side"]
    return _pick(rng, (f"<gimp> along on a bum {s} leg", f"<hobble> ahead on a busted {s} leg"))


def _s_limp(p: dict, rng: Rng) -> str:
    if p["side"] == "left":
        return _limp(p, rng)
    return _pick(rng, ("<limp>", "<limp>", "<limp> forward"))


def _e_jump_rope(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<bounce> over a turning rope {t}", f"<spring> lightly over a rope {t}",
                       f"<skip> with a rope, clearing it {t}"))


def _c_jump_rope(p: dict, rng: Rng) -> str:
    t = _times(p["count"], rng)
    return _pick(rng, (f"<bounce> over the rope {t} like a boxer", f"<skip> rope {t}"))


def _c_step_over(p: dict, rng: Rng) -> str:
    s = p["leg"]
    return _pick(rng, (f"<hike> HIS {s} leg over something in the way",
                       f"<clamber> over something, {s} leg first"))


def _c_sit_ups(p: dict, rng: Rng) -> str:
    n = _count(p["count"], rng)
    return _pick(rng, (f"<bang> out {n} sit-ups", f"<crank> out {n} crunches"))


def _s_step_over(p: dict, rng: Rng) -> str:
    """The bare phrase for the right leg, the benchmark's (which names it) for the left."""
    if p["leg"] == "left":
        return _step_over(p, rng)
    return _pick(rng, ("<step> over something", "<step> over something", "<step> over it"))

EVERYDAY: dict[str, Phrase] = {**_table(
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
    fall_forward=("<topple> forward to the floor", "<go> sprawling face down",
                  "<pitch> forward onto HIS hands and <sprawl> face down"),
    fall_backward=("<topple> over backward", "<tumble> back onto HIS back",
                   "<go> down backward and <sprawl> flat on HIS back"),
    put_down=("<lower> a box to the ground", "<crouch> and <leave> the box on the floor",
              "<rest> a box on the floor and <straighten> up"),
    long_jump=("<sprint> in and <launch> into a long jump",
               "<bound> forward off both feet after a short run"),
    stumble=("<lose> HIS footing for a moment and <steady> HIS body",
             "<catch> a toe and <lurch> forward a few steps"),
), "step_over": _e_step_over, "sit_ups": _e_sit_ups, "limp": _e_limp,
   "jump_rope": _e_jump_rope}

COLLOQUIAL: dict[str, Phrase] = {**_table(
    walk_downstairs=("<trot> down the stairs", "<clatter> down the steps"),
    walk_upstairs=("<trudge> up the stairs", "<clamber> up the steps"),
    crawl=("<scuttle> along on all fours", "<go> across the floor on all fours like a toddler"),
    carry=("<schlep> a box along", "<lug> a big box across the room"),
    push=("<muscle> something heavy forward", "<shove> a load along, leaning into it"),
    balance_walk=("<wobble> along with HIS arms out like on a tightrope",
                  "<totter> ahead, arms flung out"),
    fall_forward=("<faceplant> onto the floor", "<go> flying and <land> face first"),
    fall_backward=("<land> flat on HIS back with a thud", "<keel> over backward"),
    put_down=("<plonk> a box down on the floor", "<dump> a box on the ground"),
    stumble=("<trip> over HIS own feet and <stagger> on", "<stagger> forward, nearly going down"),
    long_jump=("<hurl> HIS body into a long jump off a run",
               "<fly> into the sand pit after a short sprint"),
), "step_over": _c_step_over, "sit_ups": _c_sit_ups, "limp": _c_limp,
   "jump_rope": _c_jump_rope}

SHORT: dict[str, Phrase] = {**_table(
    walk_downstairs=("<walk> downstairs", "<go> down the stairs", "<walk> down stairs"),
    walk_upstairs=("<walk> upstairs", "<climb> stairs", "<go> up the stairs"),
    crawl=("<crawl>", "<crawl>", "<crawl> on all fours"),
    carry=("<carry> a box", "<carry> a box", "<walk> carrying a box"),
    push=("<push> something", "<push> something", "<push> something forward"),
    balance_walk=("<walk> with arms out", "<walk> with HIS arms out"),
    fall_forward=("<fall> forward", "<fall> forward", "<fall> down"),
    fall_backward=("<fall> backward", "<fall> backward", "<fall> back"),
    sit_ups=("<do> situps", "<do> situps"),
    put_down=("<put> something down", "<put> a box down", "<put> something down"),
    jump_rope=("<jump> rope", "<jump> rope", "<skip> rope"),
    stumble=("<stumble>", "<stumble>", "<trip>"),
    long_jump=("<do> a long jump", "<do> a long jump"),
), "step_over": _s_step_over, "limp": _s_limp}


# ---------------------------------------------------------------------------- the interface

PARAMS: dict[str, dict[str, tuple]] = {
    "crawl": {}, "walk_downstairs": {}, "walk_upstairs": {},
    "step_over": {"leg": ("left", "right")},
    "fall_forward": {}, "fall_backward": {}, "sit_ups": {"count": (2, 3, 4)}, "carry": {},
    "push": {}, "put_down": {}, "limp": {"side": ("left", "right")}, "balance_walk": {},
    "jump_rope": {"count": (3, 4, 5)}, "stumble": {}, "long_jump": {},
}
CLIPS: dict[str, Callable[..., Clip]] = {
    "crawl": crawl, "walk_downstairs": walk_downstairs, "walk_upstairs": walk_upstairs,
    "step_over": step_over, "fall_forward": fall_forward, "fall_backward": fall_backward,
    "sit_ups": sit_ups, "carry": carry, "push": push, "put_down": put_down, "limp": limp,
    "balance_walk": balance_walk, "jump_rope": jump_rope, "stumble": stumble,
    "long_jump": long_jump,
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
    "benchmark": {**_forms("carry", "push", "hold", "crawl", "climb", "descend", "lead", "fall",
                          "stumble", "land", "limp", "spare", "favor"),
                  "trip": ("trips", "tripping"), "set": ("sets", "setting"),
                  "skip": ("skips", "skipping"), **_forms("catch", "recover"),
                  "tip": ("tips", "tipping")},
    "everyday": {**_forms("lug", "tote", "cart", "shove", "heave", "drive", "tiptoe", "steady",
                          "inch",
                        "creep", "mount", "clear", "topple", "pitch", "sprawl", "tumble",
                        "crunch", "curl", "work", "hobble", "nurse", "leave", "lose", "lurch",
                        "launch"),
                 "lug": ("lugs", "lugging"), "tiptoe": ("tiptoes", "tiptoeing")},
    "colloquial": {**_forms("muscle", "wobble", "totter", "scuttle", "clatter", "hike",
                            "faceplant", "keel", "crank", "gimp", "dump", "stagger", "hurl"),
                   "fly": ("flies", "flying"), "schlep": ("schleps", "schlepping")},
}
WORDS: dict[str, str] = {"box": "NOUN", "body": "NOUN", "heavy": "ADJ", "carefully": "ADV",
                         "spread": "VERB",
                         "fours": "NOUN", "flight": "NOUN", "downstairs": "ADV",
                         "upstairs": "ADV", "some": "DET",
                         "obstacle": "NOUN", "face": "NOUN", "behind": "ADP", "onto": "ADP",
                         "injured": "ADJ", "hurt": "ADJ", "unevenly": "ADV", "along": "ADV",
                         "rope": "NOUN", "small": "ADJ",
                         "but": "CCONJ", "balance": "NOUN",
                         "long": "ADJ", "far": "ADV", "few": "ADJ"}
PLURALS: dict[str, str] = {"sides": "side", "stairs": "stair", "situps": "situp"}
# A fall ends lying on the floor, and sit-ups start and end lying on the back with the knees up:
# nothing follows them in a script, and sit-ups come first.
ENDS_DOWN: frozenset[str] = frozenset({"fall_forward", "fall_backward", "sit_ups"})
STARTS_DOWN: frozenset[str] = frozenset({"sit_ups"})
