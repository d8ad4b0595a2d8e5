"""Pose-channel curves for every action family of the procedural benchmark.

Each generator returns a `Clip`: pose channels over time (see rig.pose_positions) plus the
clearance and flight information the contact solver needs. Clips start and end near the neutral
standing pose, so a script is their cross-faded concatenation. Angles in radians, distances in
metres, time in seconds; `style` carries the per-motion natural variation (amplitude, tempo).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol

import numpy as np

from mlct.data.synth.rig import SIDES, Rig

ANGLE_CHANNELS = ("yaw", "spine_bend", "spine_side", "spine_twist", "head_nod") + tuple(
    f"{name}_{s}" for name in ("hip_flex", "hip_abd", "knee", "ankle") for s in "lr")
ARM_CHANNELS = tuple(f"{name}_{s}" for name in ("wrist", "pole") for s in "lr")
# Channels of the floor families (synth/floor.py), zero in the others and outside
# ANGLE_CHANNELS, so that the posture noise draws no more random numbers than before:
# body_pitch tips the whole body about the pelvis, floor (0/1) says that the seat, back, head
# and hands may bear weight (compose.place_on_ground).
FLOOR_CHANNELS = ("body_pitch", "floor")
# The height (metres) of the ground under each foot, for stairs (zero on the flat floor, and
# zero in every family before benchmark version 4): compose.place_on_ground puts each side's
# contact points on its own ground, and a script goes on from the level a clip ended on.
GROUND_CHANNELS = ("ground_l", "ground_r")
CONTINUING = ("yaw", *GROUND_CHANNELS)  # channels a clip takes up from where the last one ended
BLEND_SECONDS = 0.4  # the cross-fade between consecutive clips


class Action(Protocol):
    """What a clip is made from (actions.Action; not imported, so that the family modules
    that actions.py merges can build on this one)."""

    family: str
    params: dict[str, Any]


@dataclass
class Style:
    """Per-motion natural variation."""

    amplitude: float = 1.0  # scales joint excursions
    tempo: float = 1.0  # > 1 is faster
    arm_length: float = 0.52  # metres, shoulder to wrist
    shoulder_x: float = 0.18  # metres from the midline to a shoulder


@dataclass
class Clip:
    """Pose channels of one action over n frames, plus flight: clearance and velocity."""

    channels: dict[str, np.ndarray]
    clearance: np.ndarray  # (n,) metres the lowest contact point is lifted off the ground
    flight: np.ndarray  # (n,) bool, no foot is planted
    flight_velocity: np.ndarray  # (n, 2) body-frame xz metres/frame during flight; nan = keep

    @property
    def n(self) -> int:
        return len(self.clearance)


def ease(x: np.ndarray) -> np.ndarray:
    """Smoothstep on [0, 1] (zero slope at both ends), clipped outside."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def envelope(t: np.ndarray, duration: float, ramp: float) -> np.ndarray:
    """1 in the middle of [0, duration], easing in and out over `ramp` seconds."""
    return ease(t / ramp) * ease((duration - t) / ramp)


def hold(t: np.ndarray, rise: float, stay: float, fall: float) -> np.ndarray:
    """0 -> 1 over `rise`, 1 for `stay`, back to 0 over `fall` (seconds)."""
    return ease(t / rise) * (1.0 - ease((t - rise - stay) / fall))


def pulses(t: np.ndarray, starts: list[float], rise: float, stay: float, fall: float) -> np.ndarray:
    """Sum of `hold` bumps starting at `starts`."""
    return sum((hold(t - s, rise, stay, fall) * (t >= s) for s in starts), np.zeros_like(t))


def relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0)


def hanging_wrist(style: Style, sign: float) -> np.ndarray:
    """Wrist target of a relaxed arm hanging at the side (chest frame, rel. to the shoulder)."""
    return np.array([0.03 * sign, -0.95 * style.arm_length, 0.03])


def neutral(n: int, style: Style) -> Clip:
    """The standing pose held for n frames."""
    channels = {name: np.zeros(n) for name in ANGLE_CHANNELS + FLOOR_CHANNELS + GROUND_CHANNELS}
    for s, sign in (("l", 1.0), ("r", -1.0)):
        channels[f"wrist_{s}"] = np.tile(hanging_wrist(style, sign), (n, 1))
        channels[f"pole_{s}"] = np.tile(np.array([0.3 * sign, 0.0, -1.0]), (n, 1))
    return Clip(channels, np.zeros(n), np.zeros(n, bool), np.full((n, 2), np.nan))


def held(clip: Clip, frame: int, n: int) -> Clip:
    """Frame `frame` of `clip` held still for n frames (lying idle before getting up)."""
    channels = {name: np.repeat(values[frame:frame + 1 or None], n, axis=0)
                for name, values in clip.channels.items()}
    return Clip(channels, np.zeros(n), np.zeros(n, bool), np.full((n, 2), np.nan))


def concatenate(clips: list[Clip], fps: float, seconds: float = BLEND_SECONDS
                ) -> tuple[Clip, list[tuple[int, int]]]:
    """Cross-fade consecutive clips over `seconds`; the heading and the ground's height
    (CONTINUING) go on from where they ended. Scripts are joined with it (compose.py), and
    the clips of a family made of parts (a run-up and a jump)."""
    overlap = int(round(seconds * fps))
    out = clips[0]
    segments = [(0, out.n)]
    for clip in clips[1:]:
        k = min(overlap, out.n // 2, clip.n // 2)
        w = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, k))  # 0 -> 1
        start = out.n - k
        channels = {}
        for name, a in out.channels.items():
            b = clip.channels[name] + (a[-1] if name in CONTINUING else 0.0)
            wk = w if a.ndim == 1 else w[:, None]
            mixed = (1 - wk) * a[start:] + wk * b[:k]
            channels[name] = np.concatenate([a[:start], mixed, b[k:]])
        clearance = np.concatenate([out.clearance[:start],
                                    np.maximum(out.clearance[start:], clip.clearance[:k]),
                                    clip.clearance[k:]])
        flight = np.concatenate([out.flight[:start], out.flight[start:] | clip.flight[:k],
                                 clip.flight[k:]])
        velocity = np.concatenate([out.flight_velocity[:start],
                                   np.where(clip.flight[:k, None], clip.flight_velocity[:k],
                                            out.flight_velocity[start:]),
                                   clip.flight_velocity[k:]])
        out = Clip(channels, clearance, flight, velocity)
        segments.append((start, out.n))
    return out, segments



def _frames(seconds: float, fps: float) -> tuple[int, np.ndarray]:
    n = max(2, int(round(seconds * fps)))
    return n, np.arange(n) / fps


def _arm(clip: Clip, side: str, wrist: np.ndarray, weight: np.ndarray,
         pole: np.ndarray | None = None) -> None:
    """Blend an arm's wrist target (and elbow pole) towards the given curves by `weight`."""
    s = side[0]
    w = weight[:, None]
    clip.channels[f"wrist_{s}"] = (1 - w) * clip.channels[f"wrist_{s}"] + w * wrist
    if pole is not None:
        clip.channels[f"pole_{s}"] = (1 - w) * clip.channels[f"pole_{s}"] + w * pole


# ---------------------------------------------------------------------------- locomotion

_GAITS = {  # stride Hz, hip amplitude, swing knee, stance knee, lean, duty factor, flight height
    "slow": (0.72, 0.24, 0.95, 0.10, 0.03, 0.62, 0.0),
    "normal": (0.88, 0.30, 1.05, 0.12, 0.05, 0.60, 0.0),
    "fast": (1.00, 0.36, 1.15, 0.14, 0.08, 0.58, 0.0),
    "jog": (1.25, 0.34, 1.5, 0.25, 0.12, 0.40, 0.04),
    "run": (1.40, 0.42, 1.8, 0.30, 0.18, 0.34, 0.07),
    "step": (0.95, 0.06, 0.9, 0.05, 0.0, 0.50, 0.0),  # stepping in place while turning
}


def hip_wave(u: np.ndarray, duty: float) -> np.ndarray:
    """Hip flexion (in units of the amplitude) over the stride phase u in [0, 1).

    Stance (u < duty) sweeps the leg back linearly, from +1 at heel strike to -1 at toe-off, so
    the body moves at a steady speed over a planted foot. Swing brings it forward on a cubic
    Hermite curve whose end slopes match the stance sweep: smooth, with the small late-swing
    retraction that lets the foot land without sliding.
    """
    slope = -2.0 / duty
    x = np.clip((u - duty) / (1.0 - duty), 0.0, 1.0)
    m = slope * (1.0 - duty)
    h00, h10 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x
    h01, h11 = -2 * x**3 + 3 * x**2, x**3 - x**2
    swing = -h00 + h10 * m + h01 + h11 * m
    return np.where(u < duty, 1.0 + slope * u, swing)


def bump(x: np.ndarray) -> np.ndarray:
    """A smooth bump: 0 outside (0, 1), peak 1 at 0.5."""
    return np.where((x > 0) & (x < 1), np.sin(np.pi * np.clip(x, 0, 1)) ** 2, 0.0)


def gait(fps: float, style: Style, kind: str, strides: float, backward: bool = False,
         yaw_total: float = 0.0) -> Clip:
    """Cyclic stepping: walk, jog, run (with flight), backwards, or in place while turning."""
    freq, amp, knee_sw, knee_st, lean, duty, flight_h = _GAITS[kind]
    freq *= style.tempo
    amp *= style.amplitude
    duration = strides / freq
    n, t = _frames(duration, fps)
    clip = neutral(n, style)
    env = envelope(t, duration, min(0.6, 0.5 / freq))
    cycles = freq * t * (-1.0 if backward else 1.0)  # backwards: the same gait played in reverse
    ch = clip.channels
    for s, offset in (("l", 0.0), ("r", 0.5)):
        u = np.mod(cycles + offset, 1.0)
        hip = amp * hip_wave(u, duty)
        # Knee: a small yield after heel strike, a large flexion from pre-swing to late swing.
        # The swing flexion peaks early and the knee straightens just before heel strike.
        swing_x = np.clip((u - duty + 0.08) / (1.02 - duty + 0.08), 0.0, 1.0)
        knee = knee_st * bump(u / duty * 0.8) + knee_sw * bump(swing_x ** 0.7)
        ch[f"hip_flex_{s}"] = env * hip
        ch[f"knee_{s}"] = env * knee
        # In swing the ankle flexes so that the foot stays about level and clears the floor,
        # eased in over the first fifth of the swing: switched on at toe-off it snapped the
        # foot 50 degrees in one frame (benchmark v1), and the toe with it.
        lift = ease(np.clip((u - duty) / (0.2 * (1.0 - duty)), 0.0, 1.0))
        ch[f"ankle_{s}"] = env * lift * relu(knee - hip)
    ch["spine_bend"] = env * lean * (-0.5 if backward else 1.0)
    phase = 2 * np.pi * cycles
    ch["spine_twist"] = env * 0.06 * amp / 0.3 * np.cos(phase)
    arm_bend = kind in ("jog", "run")
    for side, offset in (("left", 0.0), ("right", np.pi)):
        sign = 1.0 if side == "left" else -1.0
        swing = -(0.10 + 0.25 * amp) * np.cos(phase + offset)  # opposite to the same-side leg
        if arm_bend:
            wrist = np.stack([np.full(n, 0.06 * sign), np.full(n, -0.32), 0.12 + swing], -1)
        else:
            wrist = np.stack([np.full(n, 0.04 * sign), np.full(n, -0.93 * style.arm_length),
                              0.03 + 0.6 * swing], -1)
        _arm(clip, side, wrist, env)
    if duty < 0.5 and flight_h > 0:
        # Neither foot is planted between one toe-off and the other heel strike.
        u = np.mod(cycles, 0.5)
        airborne = (u > duty) & (env > 0.95)
        progress = (u - duty) / (0.5 - duty)
        clip.clearance = np.where(airborne, flight_h * np.sin(np.pi * progress), 0.0)
        clip.flight = airborne
    ch["yaw"] = yaw_total * ease(t / duration) if kind == "step" else yaw_total * t / duration
    return clip


def side_step(fps: float, style: Style, side: str, steps: int) -> Clip:
    """Lateral steps: the leading leg lifts and reaches out, the trailing leg follows."""
    step_time = 0.9 / style.tempo
    n, t = _frames(steps * step_time, fps)
    clip = neutral(n, style)
    lead, trail = side[0], ("r" if side == "left" else "l")
    amp = 0.16 * style.amplitude
    s = np.mod(t / step_time, 1.0)
    first = s < 0.5
    half = np.where(first, s * 2, s * 2 - 1)
    ch = clip.channels
    ch[f"hip_abd_{lead}"] = amp * np.where(first, ease(half), 1 - ease(half))
    ch[f"hip_abd_{trail}"] = amp * np.where(first, ease(half), 1 - ease(half))
    lift = np.sin(np.pi * half) ** 2
    for s, lifted in ((lead, first), (trail, ~first)):
        ch[f"knee_{s}"] = np.where(lifted, 0.9 * lift, 0.0)
        ch[f"hip_flex_{s}"] = np.where(lifted, 0.3 * lift, 0.0)
        ch[f"ankle_{s}"] = np.where(lifted, 0.6 * lift, 0.0)  # lift the whole foot
    return clip


# ---------------------------------------------------------------------------- whole body

def _crouch(ch: dict[str, np.ndarray], depth: np.ndarray, hip: float, knee: float,
            lean: float, sides: str = "lr") -> None:
    """Bend hips and knees by `depth` (0..1) with the feet kept flat on the ground."""
    for s in sides:
        ch[f"hip_flex_{s}"] = ch[f"hip_flex_{s}"] + hip * depth
        ch[f"knee_{s}"] = ch[f"knee_{s}"] + knee * depth
        ch[f"ankle_{s}"] = ch[f"ankle_{s}"] + (knee - hip) * depth  # foot stays level
    ch["spine_bend"] = ch["spine_bend"] + lean * depth


def jump(fps: float, style: Style, mode: str, count: int) -> Clip:
    """Crouch, take off with an arm swing, fly, land softly; forward or in place."""
    period = 1.25 / style.tempo
    n, t = _frames(count * period + 0.3, fps)
    clip = neutral(n, style)
    ch = clip.channels
    height = 0.22 * style.amplitude + (0.05 if mode == "in_place" else 0.0)
    distance = 0.7 * style.amplitude if mode == "forward" else 0.0
    crouch = np.zeros(n)
    arms_up = np.zeros(n)
    for k in range(count):
        t0 = 0.15 + k * period
        take_off, fly = t0 + 0.4 / style.tempo, 0.42
        crouch += hold(t - t0, 0.35 / style.tempo, 0.05, 0.1) * (t < take_off + 0.1)
        crouch += hold(t - (take_off + fly), 0.08, 0.05, 0.3) * (t >= take_off + fly)
        arms_up += hold(t - (take_off - 0.15), 0.15, 0.25, 0.3)
        airborne = (t >= take_off) & (t < take_off + fly)
        progress = (t - take_off) / fly
        clip.clearance = np.where(airborne, height * np.sin(np.pi * np.clip(progress, 0, 1)),
                                  clip.clearance)
        clip.flight |= airborne
        clip.flight_velocity[airborne] = [0.0, distance / (fly * fps)]
        tuck = airborne * np.sin(np.pi * np.clip(progress, 0, 1))
        for s in "lr":
            ch[f"hip_flex_{s}"] += 0.35 * tuck
            ch[f"knee_{s}"] += 0.6 * tuck
            ch[f"ankle_{s}"] -= 0.35 * tuck  # toes point down in the air
    _crouch(ch, np.clip(crouch, 0, 1) * style.amplitude, 0.75, 1.25, 0.35)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        back = np.array([0.08 * sign, -0.85 * style.arm_length, -0.25])
        up = np.array([0.1 * sign, 0.25, 0.35])
        a = np.clip(arms_up, 0, 1)[:, None]
        wrist = (1 - a) * back + a * up
        _arm(clip, side, wrist, np.clip(np.maximum(crouch, arms_up), 0, 1))
    return clip


def hop(fps: float, style: Style, leg: str, count: int) -> Clip:
    """Hops on one leg, the other held up with a bent knee, arms out for balance."""
    period = 0.62 / style.tempo
    n, t = _frames(0.8 + count * period + 0.6, fps)
    clip = neutral(n, style)
    ch = clip.channels
    free = "r" if leg == "left" else "l"
    lift = hold(t, 0.5, count * period + 0.2, 0.5)
    ch[f"hip_flex_{free}"] = 0.45 * lift
    ch[f"knee_{free}"] = 1.3 * lift
    crouch = np.zeros(n)
    for k in range(count):
        t0 = 0.6 + k * period
        crouch += hold(t - t0, 0.16, 0.0, 0.12)
        take_off, fly = t0 + 0.28, 0.26
        airborne = (t >= take_off) & (t < take_off + fly)
        progress = np.clip((t - take_off) / fly, 0, 1)
        clip.clearance = np.where(airborne, 0.1 * style.amplitude * np.sin(np.pi * progress),
                                  clip.clearance)
        clip.flight |= airborne
        clip.flight_velocity[airborne] = [0.0, 0.0]
    _crouch(ch, np.clip(crouch, 0, 1), 0.3, 0.55, 0.1, sides=leg[0])
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, np.array([0.35 * sign, -0.35, 0.1]), lift)
    return clip


def squat(fps: float, style: Style, count: int) -> Clip:
    """Deep knee bends with the arms held forward for balance."""
    period = 1.9 / style.tempo
    n, t = _frames(count * period + 0.4, fps)
    clip = neutral(n, style)
    depth = pulses(t, [0.2 + k * period for k in range(count)], 0.75 / style.tempo, 0.3,
                   0.75 / style.tempo)
    _crouch(clip.channels, depth * style.amplitude, 1.25, 2.0, 0.55)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, np.array([0.02 * sign, -0.05, 0.95 * style.arm_length]), depth)
    return clip


def sit_stand(fps: float, style: Style) -> Clip:
    """Sits down on an invisible chair, stays, stands back up."""
    down, stay, up = 1.1 / style.tempo, 1.2, 1.1 / style.tempo
    n, t = _frames(down + stay + up + 0.4, fps)
    clip = neutral(n, style)
    ch = clip.channels
    seat = hold(t - 0.2, down, stay, up)
    for s in "lr":
        ch[f"hip_flex_{s}"] = 1.45 * seat
        ch[f"knee_{s}"] = 1.5 * seat
        ch[f"ankle_{s}"] = 0.05 * seat
    # Lean forward while lowering and rising, sit upright in between.
    ch["spine_bend"] = 0.55 * np.sin(np.pi * seat) ** 2 + 0.1 * seat
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, np.array([0.06 * sign, -0.45, 0.3]), seat)
    return clip


def kneel(fps: float, style: Style, leg: str) -> Clip:
    """Goes down on one knee, stays, gets back up."""
    down, stay, up = 1.1 / style.tempo, 1.3, 1.1 / style.tempo
    n, t = _frames(down + stay + up + 0.4, fps)
    clip = neutral(n, style)
    ch = clip.channels
    knee_side, front = leg[0], ("r" if leg == "left" else "l")
    depth = hold(t - 0.2, down, stay, up)
    ch[f"hip_flex_{knee_side}"] = -0.05 * depth
    ch[f"knee_{knee_side}"] = 1.55 * depth
    ch[f"ankle_{knee_side}"] = -0.6 * depth
    ch[f"hip_flex_{front}"] = 1.45 * depth
    ch[f"knee_{front}"] = 1.5 * depth
    ch[f"ankle_{front}"] = 0.05 * depth
    ch["spine_bend"] = 0.1 * depth
    return clip


def kick(fps: float, style: Style, leg: str, count: int) -> Clip:
    """Chamber the knee, snap the leg out forward, pull it back, put the foot down."""
    period = 1.3 / style.tempo
    n, t = _frames(count * period + 0.4, fps)
    clip = neutral(n, style)
    ch = clip.channels
    s = leg[0]
    for k in range(count):
        t0 = 0.2 + k * period
        chamber = hold(t - t0, 0.35 / style.tempo, 0.45 / style.tempo, 0.35 / style.tempo)
        snap = hold(t - t0 - 0.35 / style.tempo, 0.12 / style.tempo, 0.08, 0.25 / style.tempo)
        ch[f"hip_flex_{s}"] += (0.95 * chamber + 0.35 * snap) * style.amplitude
        ch[f"knee_{s}"] += 1.5 * chamber - 1.35 * snap
        ch[f"ankle_{s}"] -= 0.3 * snap
        ch["spine_bend"] -= 0.15 * chamber
    guard = hold(t, 0.3, n / fps - 0.6, 0.3)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, side, np.array([0.3 * sign, -0.3, 0.15]), guard)
    return clip


def bow(fps: float, style: Style) -> Clip:
    """Bends forward at the waist with the head down, then straightens."""
    n, t = _frames(3.0 / style.tempo, fps)
    clip = neutral(n, style)
    depth = hold(t - 0.3, 0.9 / style.tempo, 0.6, 0.9 / style.tempo)
    clip.channels["spine_bend"] = 0.95 * style.amplitude * depth
    clip.channels["head_nod"] = 0.3 * depth
    return clip


def spin(fps: float, style: Style, side: str) -> Clip:
    """A full turn in place with quick steps."""
    sign = 1.0 if side == "left" else -1.0
    return gait(fps, style, "step", strides=2.0, yaw_total=sign * 2 * np.pi)


def turn(fps: float, style: Style, side: str, angle: int) -> Clip:
    """Steps in place while turning by `angle` degrees."""
    sign = 1.0 if side == "left" else -1.0
    return gait(fps, style, "step", strides=1.0 + angle / 90.0, yaw_total=sign * np.radians(angle))


# ---------------------------------------------------------------------------- upper body

def _gesture(fps: float, style: Style, seconds: float, n: int | None) -> tuple[int, np.ndarray, Clip]:
    """Frames, times and a neutral clip for a gesture of its own length, or stretched to n."""
    n = n or _frames(seconds, fps)[0]
    return n, np.arange(n) / fps, neutral(n, style)


def wave(fps: float, style: Style, hand: str, count: int, n: int | None = None) -> Clip:
    """Raises a hand beside the head and waves it side to side `count` times."""
    n, t, clip = _gesture(fps, style, 1.2 + count * 0.55 / style.tempo, n)
    active = max(n / fps - 1.2, 0.2)
    cycle = active / count  # exactly `count` waves, also when stretched over a walk
    raised = hold(t, 0.55, active, 0.55)
    for side in SIDES if hand == "both" else (hand,):
        sign = 1.0 if side == "left" else -1.0
        sway = 0.12 * style.amplitude * np.sin(2 * np.pi * (t - 0.55) / cycle) * (t > 0.55)
        wrist = np.stack([sign * (0.28 + sway), np.full(n, 0.22), np.full(n, 0.1)], -1)
        _arm(clip, side, wrist, raised, np.array([sign, -1.0, -0.2]))
    return clip


def raise_arms(fps: float, style: Style, hand: str, n: int | None = None) -> Clip:
    """Lifts one or both arms straight overhead, holds, lowers."""
    n, t, clip = _gesture(fps, style, 2.8 / style.tempo, n)
    up = hold(t, 0.8 / style.tempo, max(n / fps - 1.6 / style.tempo, 0.3), 0.8 / style.tempo)
    for side in SIDES if hand == "both" else (hand,):
        sign = 1.0 if side == "left" else -1.0
        wrist = np.array([0.08 * sign, 0.97 * style.arm_length, 0.06])
        _arm(clip, side, wrist, up, np.array([sign, 0.0, -0.3]))
    return clip


def clap(fps: float, style: Style, count: int, n: int | None = None) -> Clip:
    """Brings the hands together in front of the chest `count` times."""
    n, t, clip = _gesture(fps, style, 1.2 + count * 0.5 / style.tempo, n)
    active = max(n / fps - 1.2, 0.2)
    cycle = active / count  # exactly `count` claps, also when stretched over a walk
    raised = hold(t, 0.55, active, 0.55)
    # 0 = hands apart, 1 = palms together at the midline.
    closed = 0.5 - 0.5 * np.cos(2 * np.pi * np.clip(t - 0.55, 0, None) / cycle)
    for side in SIDES:
        sign = 1.0 if side == "left" else -1.0
        x = sign * (-style.shoulder_x + 0.03 + 0.22 * (1 - closed))
        wrist = np.stack([x, np.full(n, -0.12), np.full(n, 0.33)], -1)
        _arm(clip, side, wrist, raised, np.array([sign, -1.0, -0.3]))
    return clip


def punch(fps: float, style: Style, hand: str, count: int, n: int | None = None) -> Clip:
    """Fists up in guard, then `count` straight punches forward with one hand."""
    n, t, clip = _gesture(fps, style, 1.1 + count * 0.7 / style.tempo, n)
    guard = hold(t, 0.45, n / fps - 0.9, 0.45)
    period = max(n / fps - 1.1, 0.3) / count
    strike = pulses(t, [0.6 + k * period for k in range(count)], 0.15, 0.05, 0.3)
    sign_hit = 1.0 if hand == "left" else -1.0
    for side in SIDES:
        sign = 1.0 if side == "left" else -1.0
        rest = np.array([sign * (0.02 - 0.08), -0.12, 0.22])
        wrist = np.tile(rest, (n, 1))
        if side == hand:
            out = np.array([-sign * 0.1, 0.0, 0.97 * style.arm_length])
            wrist = wrist + strike[:, None] * (out - rest)
        _arm(clip, side, wrist, guard, np.array([sign, -1.0, -0.3]))
    clip.channels["spine_twist"] = -sign_hit * 0.3 * strike  # the torso turns into the punch
    return clip


def stretch(fps: float, style: Style) -> Clip:
    """Arms overhead, a lean to the left, a lean to the right, arms down."""
    n, t = _frames(5.0 / style.tempo, fps)
    clip = neutral(n, style)
    up = hold(t, 0.8 / style.tempo, n / fps - 1.6 / style.tempo, 0.8 / style.tempo)
    lean = 0.35 * style.amplitude
    seg = (n / fps - 1.6 / style.tempo) / 2
    side = hold(t - 0.8 / style.tempo, seg * 0.4, seg * 0.2, seg * 0.4) \
        - hold(t - 0.8 / style.tempo - seg, seg * 0.4, seg * 0.2, seg * 0.4)
    clip.channels["spine_side"] = lean * side
    for arm, sign in (("left", 1.0), ("right", -1.0)):
        _arm(clip, arm, np.array([0.06 * sign, 0.97 * style.arm_length, 0.02]), up,
             np.array([sign, 0.0, -0.3]))
    return clip


def stand(fps: float, style: Style) -> Clip:
    """Stands still with a slight idle sway."""
    n, t = _frames(2.0 + style.tempo, fps)
    clip = neutral(n, style)
    clip.channels["spine_side"] = 0.02 * np.sin(2 * np.pi * 0.3 * t)
    return clip


_UPPER: dict[str, Callable[..., Clip]] = {"wave": wave, "raise_arms": raise_arms, "clap": clap,
                                          "punch": punch}


def base_clip(action: Action, rig: Rig, style: Style, fps: float) -> Clip:
    """The clip of one action of benchmark version 2's families (more_clips.action_clip: any)."""
    p, f = action.params, action.family
    if f == "walk":
        return gait(fps, style, p["speed"], strides=3 + style.tempo)
    if f == "walk_backward":
        return gait(fps, style, p["speed"], strides=2.5 + style.tempo, backward=True)
    if f in ("jog", "run"):
        return gait(fps, style, f, strides=3.5 + style.tempo)
    if f == "circle":
        return gait(fps, style, "normal", strides=6.0,
                    yaw_total=(1.0 if p["side"] == "left" else -1.0) * 2 * np.pi)
    if f == "side_step":
        return side_step(fps, style, p["side"], p["steps"])
    if f == "turn":
        return turn(fps, style, p["side"], p["angle"])
    if f == "spin":
        return spin(fps, style, p["side"])
    if f == "jump":
        return jump(fps, style, p["mode"], p["count"])
    if f == "hop":
        return hop(fps, style, p["leg"], p["count"])
    if f == "squat":
        return squat(fps, style, p["count"])
    if f == "sit_stand":
        return sit_stand(fps, style)
    if f == "kneel":
        return kneel(fps, style, p["leg"])
    if f == "kick":
        return kick(fps, style, p["leg"], p["count"])
    if f == "bow":
        return bow(fps, style)
    if f == "stretch":
        return stretch(fps, style)
    if f == "stand":
        return stand(fps, style)
    if f in _UPPER:
        return _UPPER[f](fps, style, **p)
    raise ValueError(f"no motion for action family {f!r}")


def overlay_upper(base: Clip, action: Action, style: Style, fps: float) -> Clip:
    """`base` (locomotion) with the arms (and torso twist) of an upper-body action on top."""
    upper = _UPPER[action.family](fps, style, **action.params, n=base.n)
    # Clapping and the punching guard use both arms; waving / raising one or both.
    both = action.family in ("clap", "punch") or action.params.get("hand") == "both"
    for side in SIDES if both else (action.params["hand"],):
        s = side[0]
        base.channels[f"wrist_{s}"] = upper.channels[f"wrist_{s}"]
        base.channels[f"pole_{s}"] = upper.channels[f"pole_{s}"]
    base.channels["spine_twist"] = base.channels["spine_twist"] + upper.channels["spine_twist"]
    return base
