"""Physical read-outs of a motion, and checks that say whether it does what its text says.

A learned evaluator (R-precision, FID, the action classifier) scores a motion against a
distribution; it cannot say *why* a "left wave" is wrong. The read-outs here are plain physical
observables measured on the joints: how far the pelvis moved along the body's initial facing,
how much the body turned, whether the feet left the floor, which wrist went above the head.
Each is a small pure-numpy function of joints (T, 22, 3) in metres in the HumanML3D convention
(y up, floor at y = 0, 20 fps).

`checks_for` maps one action of the procedural benchmark (labels.jsonl: a family and its
params) to the read-outs it must show ("walk": the pelvis travels forward and the feet
alternate; "wave left": the left wrist rises to the head and sways while the right stays
down). `evaluate_label` applies them to every action of a labels.jsonl record inside its time
window. The thresholds sit between what the benchmark's own motions of a family show and what
motions of the other families show: on a 4,000-motion benchmark (seed 0) every ground-truth
motion passes, and a family's checks pass no single-action clip of another family except
where the motions overlap (a stretch raises both arms; the fastest jogs and slowest runs).
They hold under 5 mm of per-joint jitter; 1 cm of jitter makes some walks look airborne.

Conventions. "Forward" and "left" are relative to the body's facing at the clip's (window's)
first frame: forward = up x (right hip - left hip + right shoulder - left shoulder), left =
up x forward; the person's left, not the viewer's. Headings are counter-clockwise seen from
above (a rotation about +y): a turn to the person's left is positive; at the HumanML3D start
facing +Z, the left is +X.
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, fields
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from mlct.motion import gait
from mlct.motion.skeleton import HUMANML3D

FPS = HUMANML3D.fps
SIDES = ("left", "right")
_UP = np.array([0.0, 1.0, 0.0])

_J = HUMANML3D.index
PELVIS, NECK, HEAD = _J("pelvis"), _J("neck"), _J("head")
R_HIP, L_HIP, R_SHOULDER, L_SHOULDER = HUMANML3D.face_joints
WRIST = {"left": _J("left_wrist"), "right": _J("right_wrist")}
SHOULDER = {"left": L_SHOULDER, "right": R_SHOULDER}
ANKLE = {"left": HUMANML3D.foot_left[0], "right": HUMANML3D.foot_right[0]}
FOOT = {"left": HUMANML3D.foot_left, "right": HUMANML3D.foot_right}  # ankle, toe
KNEE = {"left": _J("left_knee"), "right": _J("right_knee")}


def _other(side: str) -> str:
    return "right" if side == "left" else "left"


# ---------------------------------------------------------------------------- input and frames

def as_joints(joints: Any) -> np.ndarray:
    """The joints as a float64 (T, 22, 3) array in metres; anything else raises ValueError."""
    array = np.asarray(joints, dtype=np.float64)
    if array.ndim != 3 or array.shape[1:] != (HUMANML3D.n_joints, 3) or len(array) < 2:
        raise ValueError(f"read-outs need HumanML3D joints of shape (T >= 2, 22, 3) in metres, "
                         f"got shape {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError("joints contain NaN or infinite values")
    # A body several metres tall is a motion in other units (KIT-ML is in millimetres).
    extent = np.ptp(array[0, :, 1])
    if extent > 4.0:
        raise ValueError(f"joints must be in metres: the first pose is {extent:.1f} units tall")
    return array


def facing(joints: np.ndarray) -> np.ndarray:
    """(T, 3) horizontal unit forward vector of the body, from its hips and shoulders."""
    across = (joints[:, R_HIP] - joints[:, L_HIP]) + (joints[:, R_SHOULDER] - joints[:, L_SHOULDER])
    forward = np.cross(_UP, across)
    forward[:, 1] = 0.0
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)


def heading(joints: np.ndarray) -> np.ndarray:
    """(T,) unwrapped facing angle in radians, counter-clockwise seen from above (left-positive)."""
    forward = facing(joints)
    return np.unwrap(np.arctan2(forward[:, 0], forward[:, 2]))


def _initial_axes(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward and left unit vectors of the body at the first frame."""
    forward = facing(joints[:1])[0]
    return forward, np.cross(_UP, forward)


def _lowest_foot(joints: np.ndarray) -> np.ndarray:
    """(T,) height of the lowest foot joint (ankles and toes)."""
    feet = list(FOOT["left"]) + list(FOOT["right"])
    return joints[:, feet, 1].min(axis=1)


def _floor(joints: np.ndarray) -> float:
    """The clip's floor level: the median height of the lowest foot joint. A body stands on
    the floor most of the time (jumps are in the air a third of it at most), and the median
    is not pulled down by jitter the way the minimum or a low percentile is."""
    return float(np.median(_lowest_foot(joints)))


def _standing(values: np.ndarray) -> float:
    """The standing value of a height: the median over the first 5 frames."""
    return float(np.median(values[:5]))


def _count_episodes(mask: np.ndarray, min_gap: int = 2) -> int:
    """Number of runs of True in `mask`, runs closer than `min_gap` frames merged."""
    count, gap = 0, min_gap
    for value in mask:
        if value:
            if gap >= min_gap:
                count += 1
            gap = 0
        else:
            gap += 1
    return count


def _count_entries(values: np.ndarray, enter: float, leave: float) -> int:
    """How often `values` drops below `enter`, re-armed only once it is back above `leave`."""
    count, armed = 0, True
    for value in values:
        if armed and value < enter:
            count, armed = count + 1, False
        elif not armed and value > leave:
            armed = True
    return count


def _count_rises(values: np.ndarray, enter: float, leave: float) -> int:
    """How often `values` rises above `enter`, re-armed only once it is back below `leave`."""
    return _count_entries(-values, -enter, -leave)


def _reversals(values: np.ndarray, hysteresis: float) -> int:
    """Direction changes of a 1-D signal, each undoing at least `hysteresis` of its travel."""
    count, direction = 0, 0  # direction: +1 rising, -1 falling, 0 not yet known
    high = low = values[0] if len(values) else 0.0
    for value in values:
        high, low = max(high, value), min(low, value)
        if direction >= 0 and value < high - hysteresis:
            count, direction, low = count + (direction > 0), -1, value
        elif direction <= 0 and value > low + hysteresis:
            count, direction, high = count + (direction < 0), 1, value
    return count


# ---------------------------------------------------------------------------- travel and turning

def forward_displacement(joints: np.ndarray) -> float:
    """Metres the pelvis travels along the body's initial forward axis (negative = backwards)."""
    joints = as_joints(joints)
    forward, _ = _initial_axes(joints)
    return float((joints[-1, PELVIS] - joints[0, PELVIS]) @ forward)


def lateral_displacement(joints: np.ndarray) -> float:
    """Metres the pelvis travels sideways; positive = towards the person's initial left."""
    joints = as_joints(joints)
    _, left = _initial_axes(joints)
    return float((joints[-1, PELVIS] - joints[0, PELVIS]) @ left)


def heading_change(joints: np.ndarray) -> float:
    """Radians turned, unwrapped; positive = to the person's left (counter-clockwise from above)."""
    angle = heading(as_joints(joints))
    return float(angle[-1] - angle[0])


def pelvis_path(joints: np.ndarray, step: int = 5) -> float:
    """Metres of horizontal pelvis path, sampled every `step` frames (so jitter does not add up)."""
    joints = as_joints(joints)
    track = joints[::step, PELVIS][:, [0, 2]]
    if (len(joints) - 1) % step:
        track = np.vstack([track, joints[-1:, PELVIS][:, [0, 2]]])
    return float(np.linalg.norm(np.diff(track, axis=0), axis=-1).sum())


def peak_speed(joints: np.ndarray, seconds: float = 1.0) -> float:
    """Highest horizontal pelvis speed (m/s) held over `seconds` (the whole clip if shorter)."""
    joints = as_joints(joints)
    lag = min(int(round(seconds * FPS)), len(joints) - 1)
    ground = joints[:, PELVIS][:, [0, 2]]
    return float(np.linalg.norm(ground[lag:] - ground[:-lag], axis=-1).max() * FPS / lag)


# ---------------------------------------------------------------------------- up and down

def pelvis_rise(joints: np.ndarray) -> float:
    """Metres the pelvis rises above its standing height (median of the first 5 frames)."""
    height = as_joints(joints)[:, PELVIS, 1]
    return float(height.max() - _standing(height))


def pelvis_drop(joints: np.ndarray) -> float:
    """Metres the pelvis sinks below its standing height (median of the first 5 frames)."""
    height = as_joints(joints)[:, PELVIS, 1]
    return float(_standing(height) - height.min())


def pelvis_dips(joints: np.ndarray, depth: float = 0.15) -> int:
    """Separate times the pelvis sinks more than `depth` m below standing (squats, sits)."""
    height = as_joints(joints)[:, PELVIS, 1]
    below = _standing(height) - height
    # Re-armed halfway back up, so the bounce at the bottom of a squat is one dip.
    return _count_rises(below, depth, depth / 2)


def low_hold(joints: np.ndarray, depth: float = 0.15) -> float:
    """Longest time (s) the pelvis stays more than `depth` m below standing (sitting holds)."""
    height = as_joints(joints)[:, PELVIS, 1]
    low = _standing(height) - height > depth
    longest = run = 0
    for value in low:
        run = run + 1 if value else 0
        longest = max(longest, run)
    return longest / FPS


def pelvis_setback(joints: np.ndarray) -> float:
    """Max distance (m) of the pelvis behind the midpoint of the ankles, along the body's facing:
    sitting on a chair puts it well behind the feet, a squat keeps it over them."""
    joints = as_joints(joints)
    behind = (0.5 * (joints[:, ANKLE["left"]] + joints[:, ANKLE["right"]]) - joints[:, PELVIS])
    return float(np.einsum("ti,ti->t", behind, facing(joints)).max())


def airborne_frames(joints: np.ndarray, clearance: float = 0.05) -> int:
    """Frames in which the lowest foot joint is more than `clearance` m above the clip's floor."""
    joints = as_joints(joints)
    return int((_lowest_foot(joints) > _floor(joints) + clearance).sum())


def flight_frames(joints: np.ndarray) -> int:
    """Frames with both feet off the floor by more than 2 cm: a running gait's flight phase."""
    return airborne_frames(joints, clearance=0.02)


def airborne_episodes(joints: np.ndarray, clearance: float = 0.05) -> int:
    """Separate flights: runs of airborne frames (gaps of a single frame merged)."""
    joints = as_joints(joints)
    return _count_episodes(_lowest_foot(joints) > _floor(joints) + clearance)


def knee_clearance(joints: np.ndarray) -> dict[str, float]:
    """Per side, the lowest height (m) of the knee above the clip's floor (~0 when kneeling)."""
    joints = as_joints(joints)
    floor = _floor(joints)
    return {s: float(joints[:, KNEE[s], 1].min() - floor) for s in SIDES}


# ---------------------------------------------------------------------------- feet

def foot_swaps(joints: np.ndarray, hysteresis: float = 0.03) -> int:
    """How often the lower foot changes side; a change counts once the other foot is lower by
    more than `hysteresis` m, so two feet planted side by side do not flicker."""
    return gait.foot_swaps(as_joints(joints), HUMANML3D, hysteresis)


def foot_travel(joints: np.ndarray) -> dict[str, float]:
    """Per side, metres of horizontal path of the ankle."""
    joints = as_joints(joints)
    return {s: float(np.linalg.norm(np.diff(joints[:, ANKLE[s]][:, [0, 2]], axis=0), axis=-1).sum())
            for s in SIDES}


def foot_lift(joints: np.ndarray) -> dict[str, float]:
    """Per side, metres the ankle rises above its standing height (median of the first 5 frames)."""
    joints = as_joints(joints)
    return {s: float(joints[:, ANKLE[s], 1].max() - _standing(joints[:, ANKLE[s], 1]))
            for s in SIDES}


def _reach_series(joints: np.ndarray, joint: int) -> np.ndarray:
    """(T,) distance of `joint` in front of the pelvis along the body's facing at each frame."""
    offset = joints[:, joint] - joints[:, PELVIS]
    return np.einsum("ti,ti->t", offset, facing(joints))


def _reach(joints: np.ndarray, joint: int) -> float:
    """Max distance of `joint` in front of the pelvis along the body's facing at each frame."""
    return float(_reach_series(joints, joint).max())


def foot_thrusts(joints: np.ndarray, out: float = 0.4, back: float = 0.25) -> dict[str, int]:
    """Per side, separate times the ankle goes more than `out` m in front of the pelvis (kicks);
    re-armed once it is back within `back` m."""
    joints = as_joints(joints)
    return {s: _count_rises(_reach_series(joints, ANKLE[s]), out, back) for s in SIDES}


def foot_reach(joints: np.ndarray) -> dict[str, float]:
    """Per side, max forward distance (m) of the ankle from the pelvis in the body frame."""
    joints = as_joints(joints)
    return {s: _reach(joints, ANKLE[s]) for s in SIDES}


# ---------------------------------------------------------------------------- hands and torso

def wrist_height(joints: np.ndarray) -> dict[str, float]:
    """Per side, max height (m) of the wrist relative to the head joint (positive = above)."""
    joints = as_joints(joints)
    return {s: float((joints[:, WRIST[s], 1] - joints[:, HEAD, 1]).max()) for s in SIDES}


def wrist_reach(joints: np.ndarray) -> dict[str, float]:
    """Per side, max forward distance (m) of the wrist from the pelvis in the body frame."""
    joints = as_joints(joints)
    return {s: _reach(joints, WRIST[s]) for s in SIDES}


def wrist_sway(joints: np.ndarray, hysteresis: float = 0.05) -> dict[str, int]:
    """Per side, side-to-side reversals of the wrist while raised above its shoulder (waving)."""
    joints = as_joints(joints)
    left = np.cross(_UP, facing(joints))
    sway = {}
    for s in SIDES:
        raised = joints[:, WRIST[s], 1] > joints[:, SHOULDER[s], 1]
        # Relative to the neck, so that the body's own sway and travel do not count.
        lateral = np.einsum("ti,ti->t", joints[:, WRIST[s]] - joints[:, NECK], left)
        sway[s] = _reversals(lateral[raised], hysteresis)
    return sway


def wrist_thrusts(joints: np.ndarray, out: float = 0.35, back: float = 0.28) -> dict[str, int]:
    """Per side, separate times the wrist goes more than `out` m in front of the pelvis
    (punches); re-armed once it is back within `back` m."""
    joints = as_joints(joints)
    return {s: _count_rises(_reach_series(joints, WRIST[s]), out, back) for s in SIDES}


def _hand_gap(joints: np.ndarray) -> np.ndarray:
    return np.linalg.norm(joints[:, WRIST["left"]] - joints[:, WRIST["right"]], axis=-1)


def hand_gap_minima(joints: np.ndarray, close: float = 0.15) -> int:
    """Separate times the wrists come within `close` m (re-armed once 5 cm further apart)."""
    return _count_entries(_hand_gap(as_joints(joints)), close, close + 0.05)


def min_hand_gap(joints: np.ndarray) -> float:
    """Smallest distance (m) between the wrists."""
    return float(_hand_gap(as_joints(joints)).min())


def _torso_angles(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T,) pitch (forward-positive) and roll (left-positive) of pelvis->neck from vertical."""
    forward = facing(joints)
    left = np.cross(_UP, forward)
    spine = joints[:, NECK] - joints[:, PELVIS]
    vertical = spine[:, 1]
    pitch = np.arctan2(np.einsum("ti,ti->t", spine, forward), vertical)
    roll = np.arctan2(np.einsum("ti,ti->t", spine, left), vertical)
    return pitch, roll


def torso_pitch(joints: np.ndarray) -> float:
    """Max forward lean (radians) of the pelvis->neck vector from vertical."""
    return float(_torso_angles(as_joints(joints))[0].max())


def torso_side_lean(joints: np.ndarray) -> dict[str, float]:
    """Max sideways lean (radians) of the pelvis->neck vector towards each side."""
    roll = _torso_angles(as_joints(joints))[1]
    return {"left": float(roll.max()), "right": float(-roll.min())}


# ---------------------------------------------------------------------------- all at once

@dataclass(frozen=True)
class Readouts:
    """Every read-out of one motion (metres, radians, frame counts; sides are the person's)."""

    forward_displacement: float
    lateral_displacement: float
    heading_change: float
    pelvis_path: float
    peak_speed: float
    pelvis_rise: float
    pelvis_drop: float
    pelvis_dips: int
    low_hold: float
    pelvis_setback: float
    airborne_frames: int
    flight_frames: int
    airborne_episodes: int
    knee_clearance: dict[str, float]
    foot_swaps: int
    foot_travel: dict[str, float]
    foot_lift: dict[str, float]
    foot_reach: dict[str, float]
    foot_thrusts: dict[str, int]
    wrist_height: dict[str, float]
    wrist_reach: dict[str, float]
    wrist_sway: dict[str, int]
    wrist_thrusts: dict[str, int]
    hand_gap_minima: int
    min_hand_gap: float
    torso_pitch: float
    torso_side_lean: dict[str, float]

    @classmethod
    def of(cls, joints: np.ndarray) -> "Readouts":
        """Measure every read-out on joints (T, 22, 3) in metres."""
        joints = as_joints(joints)
        return cls(**{f.name: _READOUTS[f.name](joints) for f in fields(cls)})

    def as_dict(self) -> dict[str, float]:
        """Flat {name: value}; per-side read-outs become 'name.left' and 'name.right'."""
        flat: dict[str, float] = {}
        for name, value in asdict(self).items():
            if isinstance(value, dict):
                flat.update({f"{name}.{side}": float(v) for side, v in value.items()})
            else:
                flat[name] = float(value)
        return flat


_READOUTS: dict[str, Callable[[np.ndarray], Any]] = {
    "forward_displacement": forward_displacement, "lateral_displacement": lateral_displacement,
    "heading_change": heading_change, "pelvis_path": pelvis_path, "peak_speed": peak_speed,
    "pelvis_rise": pelvis_rise, "pelvis_drop": pelvis_drop, "pelvis_dips": pelvis_dips,
    "low_hold": low_hold, "pelvis_setback": pelvis_setback, "airborne_frames": airborne_frames,
    "flight_frames": flight_frames, "airborne_episodes": airborne_episodes,
    "knee_clearance": knee_clearance, "foot_swaps": foot_swaps, "foot_travel": foot_travel,
    "foot_lift": foot_lift, "foot_reach": foot_reach, "foot_thrusts": foot_thrusts,
    "wrist_height": wrist_height, "wrist_reach": wrist_reach, "wrist_sway": wrist_sway,
    "wrist_thrusts": wrist_thrusts, "hand_gap_minima": hand_gap_minima,
    "min_hand_gap": min_hand_gap, "torso_pitch": torso_pitch, "torso_side_lean": torso_side_lean,
}


# The families benchmark version 3 adds register their read-outs and checks here: their module
# (readouts_more.py) builds on this one, and mlct.eval's __init__ imports it, so both are in
# place whenever anything of mlct.eval is.
EXTRA_READINGS: list[Callable[[np.ndarray], dict[str, float]]] = []
EXTRA_CHECKS: dict[str, Callable[[str, Mapping[str, Any]], list]] = {}


def read_all(joints: np.ndarray) -> dict[str, float]:
    """Every read-out of a motion as a flat {name: value} dict (see `Readouts.as_dict`), with
    those of the families benchmark version 3 adds (EXTRA_READINGS)."""
    joints = as_joints(joints)
    out = Readouts.of(joints).as_dict()
    for more in EXTRA_READINGS:
        out.update(more(joints))
    return out


# ---------------------------------------------------------------------------- windows

def action_windows(label: Mapping[str, Any], n_frames: int, margin: float = 0.0,
                   fps: float = FPS) -> list[tuple[int, int]]:
    """Frame windows [lo, hi) of each action of a labels.jsonl record in a clip of n_frames.

    Consecutive actions of the benchmark cross-fade: their labelled [start, end] overlap by the
    fade (0.4 s). Each window runs from the middle of one fade to the middle of the next,
    widened by `margin` seconds at those inner boundaries; the first and last windows reach the
    clip's ends (the lead-in and lead-out are idle), so a single action is judged on the whole
    clip. The default margin is 0: a wider window takes in the start of the next action (0.1 s
    more let a turn followed by a spin read up to 20 degrees of the spin). Times are scaled by
    n_frames / label["frames"], so a generated clip of another length is cut at the same
    fractions of its duration.
    """
    actions = label["actions"]
    scale = n_frames / label["frames"] if label.get("frames") else 1.0
    bounds = [0.0]
    for before, after in zip(actions[:-1], actions[1:]):
        bounds.append(0.5 * (float(after["start"]) + float(before["end"])) * fps * scale)
    bounds.append(float(n_frames))
    windows = []
    for i in range(len(actions)):
        lo = bounds[i] - (margin * fps if i > 0 else 0.0)
        hi = bounds[i + 1] + (margin * fps if i < len(actions) - 1 else 0.0)
        lo_frame = int(np.clip(round(lo), 0, n_frames - 2))
        windows.append((lo_frame, int(np.clip(round(hi), lo_frame + 2, n_frames))))
    return windows


# ---------------------------------------------------------------------------- checks

Readings = Mapping[str, float]


@dataclass(frozen=True)
class Check:
    """One physical condition an action must meet, as a test on the read-out dict."""

    name: str  # "family.what", e.g. "wave.hand_up"
    description: str
    test: Callable[[Readings], bool]

    def __call__(self, readings: Readings) -> bool:
        return bool(self.test(readings))


# Thresholds sit between what the benchmark's own motions of the family show (its ground
# truth, the comments give its range) and what motions that do not do the action show.
TURN_TOLERANCE = np.radians(22.5)  # half the step between the labelled angles (45, 90, ...)
FULL_TURN = 1.5 * np.pi  # a spin or a circle turns at least 270 degrees (GT: 336 or more)
CIRCLE_PATH = 2.5  # metres of pelvis path that separate a circle (GT >= 4.5) from a spin (<= 1.5)


def _sign(side: str) -> float:
    return 1.0 if side == "left" else -1.0


def _sides(hand: str) -> tuple[str, ...]:
    return SIDES if hand == "both" else (hand,)


def _gait_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """walk, walk_backward, jog, run: travel along the facing on alternating feet."""
    checks = [Check(f"{family}.steps", "the lower foot alternates at least twice",
                    lambda r: r["foot_swaps"] >= 2),
              Check(f"{family}.straight", "turns less than 30 degrees",
                    lambda r: abs(r["heading_change"]) < np.radians(30))]
    if family in ("walk", "walk_backward"):
        # A walk always has a foot on the floor (GT: 0 frames with both feet 2 cm up); jog and
        # run have flight phases (GT: 5 frames or more). The slack absorbs a few mm of jitter.
        checks.append(Check(f"{family}.no_flight", "both feet 2 cm off the floor in at most "
                            "3 frames", lambda r: r["flight_frames"] <= 3))
        speed = params.get("speed")
        # GT peak speeds (m/s over 1 s): slow 0.56-0.97, normal 0.77-1.37, fast 1.00-1.90.
        if speed == "slow":
            checks.append(Check(f"{family}.slow", "peak speed under 1.1 m/s",
                                lambda r: r["peak_speed"] < 1.1))
        elif speed == "fast":
            checks.append(Check(f"{family}.fast", "peak speed over 0.9 m/s",
                                lambda r: r["peak_speed"] > 0.9))
    if family == "walk":  # GT: 2.3-5.0 m forward
        checks.append(Check("walk.forward", "the pelvis moves over 1 m forward",
                            lambda r: r["forward_displacement"] > 1.0))
    elif family == "walk_backward":  # GT: 2.3-4.9 m backwards
        checks.append(Check("walk_backward.backward", "the pelvis moves over 1 m backwards",
                            lambda r: r["forward_displacement"] < -1.0))
    elif family == "jog":  # GT: 4.4-8.0 m, 1.3-2.9 m/s
        checks += [Check("jog.forward", "the pelvis moves over 2 m forward",
                         lambda r: r["forward_displacement"] > 2.0),
                   Check("jog.pace", "peak speed between 1.2 and 3.2 m/s (faster than a walk, "
                         "slower than a run)", lambda r: 1.2 < r["peak_speed"] < 3.2),
                   Check("jog.flight", "both feet 2 cm off the floor in at least 4 frames",
                         lambda r: r["flight_frames"] >= 4)]
    elif family == "run":  # GT: 6.5-10.8 m, 2.8-4.8 m/s
        checks += [Check("run.forward", "the pelvis moves over 3 m forward",
                         lambda r: r["forward_displacement"] > 3.0),
                   Check("run.pace", "peak speed over 2.5 m/s", lambda r: r["peak_speed"] > 2.5),
                   Check("run.flight", "both feet 2 cm off the floor in at least 4 frames",
                         lambda r: r["flight_frames"] >= 4)]
    return checks


def _turning_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """turn, spin, circle: the heading changes to the named side by the named amount."""
    side = params.get("side")
    sign = _sign(side) if side else None

    def turned(r: Readings) -> float:  # radians turned towards the named side (any if none)
        return sign * r["heading_change"] if sign else abs(r["heading_change"])

    where = f" to the {side}" if side else ""
    if family == "turn":
        angle = params.get("angle")
        if angle is None:  # no angle named: any clear turn
            return [Check("turn.heading", f"turns{where} by 30 degrees or more",
                          lambda r: turned(r) > np.radians(30))]
        target = np.radians(angle)
        return [Check("turn.heading", f"turns{where} by {angle} +- 22.5 degrees",
                      lambda r: abs(turned(r) - target) < TURN_TOLERANCE)]
    checks = [Check(f"{family}.heading", f"turns{where} by 270 degrees or more",
                    lambda r: turned(r) > FULL_TURN)]
    if family == "spin":
        checks.append(Check("spin.in_place", f"pelvis path under {CIRCLE_PATH} m",
                            lambda r: r["pelvis_path"] < CIRCLE_PATH))
    else:
        checks += [Check("circle.path", f"pelvis path over {CIRCLE_PATH} m",
                         lambda r: r["pelvis_path"] > CIRCLE_PATH),
                   Check("circle.steps", "the lower foot alternates at least twice",
                         lambda r: r["foot_swaps"] >= 2)]
    return checks


def _side_step_checks(params: Mapping[str, Any]) -> list[Check]:
    side = params.get("side")
    checks = [Check("side_step.steps", "the lower foot alternates at least twice",
                    lambda r: r["foot_swaps"] >= 2),
              Check("side_step.facing", "turns less than 30 degrees",
                    lambda r: abs(r["heading_change"]) < np.radians(30))]
    if side:  # GT: 0.3-1.0 m to the named side
        sign = _sign(side)
        checks.append(Check("side_step.side", f"the pelvis moves over 0.2 m to the {side}",
                            lambda r: sign * r["lateral_displacement"] > 0.2))
    else:
        checks.append(Check("side_step.side", "the pelvis moves over 0.2 m sideways",
                            lambda r: abs(r["lateral_displacement"]) > 0.2))
    checks.append(Check("side_step.sideways", "moves more sideways than forward or back",
                        lambda r: abs(r["lateral_displacement"]) > abs(r["forward_displacement"])))
    return checks


def _jump_checks(params: Mapping[str, Any]) -> list[Check]:
    # GT: the pelvis rises 0.20-0.37 m, 7+ airborne frames per jump; hops rise <= 0.13 m.
    checks = [Check("jump.rise", "the pelvis rises over 0.16 m above standing",
                    lambda r: r["pelvis_rise"] > 0.16),
              Check("jump.airborne", "both feet 5 cm off the floor in at least 3 frames",
                    lambda r: r["airborne_frames"] >= 3),
              Check("jump.both_feet", "the two ankles lift within 0.1 m of each other",
                    lambda r: abs(r["foot_lift.left"] - r["foot_lift.right"]) < 0.1)]
    checks += _count_check(params, "jump.count", "{} separate flights", "airborne_episodes")
    mode = params.get("mode")
    if mode == "forward":  # GT: 0.67 m or more
        checks.append(Check("jump.forward", "the pelvis lands over 0.5 m further forward",
                            lambda r: r["forward_displacement"] > 0.5))
    elif mode == "in_place":  # GT: within 0.4 m
        checks.append(Check("jump.in_place", "the pelvis lands within 0.5 m of where it took off",
                            lambda r: abs(r["forward_displacement"]) < 0.5))
    return checks


def _count_check(params: Mapping[str, Any], name: str, what: str, readout: str) -> list[Check]:
    """The check that `readout` equals the label's count, when the label has one."""
    count = params.get("count")
    if not count:
        return []
    return [Check(name, what.format(count), lambda r: r[readout] == count)]


def _hop_checks(params: Mapping[str, Any]) -> list[Check]:
    checks = [Check("hop.airborne", "the hopping foot 5 cm off the floor in at least 3 frames",
                    lambda r: r["airborne_frames"] >= 3)]
    checks += _count_check(params, "hop.count", "{} separate flights", "airborne_episodes")
    leg = params.get("leg")
    if leg:  # GT: the free ankle lifts 0.09-0.25 m more than the hopping one
        other = _other(leg)
        checks.append(Check("hop.leg", f"the {other} foot is held up: its ankle lifts 6 cm more "
                            f"than the {leg} one", lambda r: r[f"foot_lift.{other}"]
                            - r[f"foot_lift.{leg}"] > 0.06))
    else:
        checks.append(Check("hop.leg", "one foot is held up: the ankles lift 6 cm apart",
                            lambda r: abs(r["foot_lift.left"] - r["foot_lift.right"]) > 0.06))
    return checks


def _lowering_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """squat, sit_stand, kneel: the pelvis goes down and comes back up."""
    # GT: the pelvis sinks 0.30-0.53 m; the crouch before and after a jump 0.10-0.23 m.
    checks = [Check(f"{family}.drop", "the pelvis sinks over 0.25 m below standing",
                    lambda r: r["pelvis_drop"] > 0.25),
              Check(f"{family}.grounded", "the feet stay on the floor (at most 1 frame 5 cm up)",
                    lambda r: r["airborne_frames"] <= 1)]
    knees_up = Check(f"{family}.knees_up", "both knees stay over 0.2 m above the floor "
                     "(not kneeling)", lambda r: min(r["knee_clearance.left"],
                                                     r["knee_clearance.right"]) > 0.2)
    # GT: sitting puts the pelvis 0.33-0.36 m behind the ankles, a squat 0.05-0.09 m.
    if family == "squat":
        checks += [knees_up, Check("squat.over_feet", "the pelvis stays within 0.2 m behind "
                                   "the ankles (sitting back is a sit)",
                                   lambda r: r["pelvis_setback"] < 0.2)]
        count = params.get("count")
        if count:
            checks.append(Check("squat.count", f"{count} separate dips",
                                lambda r: r["pelvis_dips"] == count))
    elif family == "sit_stand":
        # GT: down 1.95-2.35 s; a squat stays down 0.8-1.15 s.
        checks += [knees_up, Check("sit_stand.once", "one dip", lambda r: r["pelvis_dips"] == 1),
                   Check("sit_stand.sits_back", "the pelvis goes over 0.2 m behind the ankles",
                         lambda r: r["pelvis_setback"] > 0.2),
                   Check("sit_stand.hold", "stays down for 1.5 s or more",
                         lambda r: r["low_hold"] >= 1.5)]
    else:
        leg = params.get("leg")
        if leg:  # GT: the kneeling knee 0.09-0.15 m above the floor, the other 0.46 m
            other = _other(leg)
            checks += [Check("kneel.knee_down", f"the {leg} knee comes within 0.22 m of the floor",
                             lambda r: r[f"knee_clearance.{leg}"] < 0.22),
                       Check("kneel.other_knee_up", f"the {other} knee stays 0.15 m higher",
                             lambda r: r[f"knee_clearance.{other}"]
                             > r[f"knee_clearance.{leg}"] + 0.15)]
        else:
            checks.append(Check("kneel.knee_down", "a knee comes within 0.22 m of the floor",
                                lambda r: min(r["knee_clearance.left"],
                                              r["knee_clearance.right"]) < 0.22))
    return checks


def _arm_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """wave, raise_arms: the named hand(s) up, the other down; a wave sways side to side."""
    hand = params.get("hand", "both")
    checks = []
    for side in _sides(hand):
        if family == "wave":  # GT: the waving wrist 0.06-0.14 m above the head joint
            checks += [Check(f"wave.{side}_up", f"the {side} wrist rises to head height",
                             lambda r, s=side: r[f"wrist_height.{s}"] > -0.05),
                       Check(f"wave.{side}_sway", f"the raised {side} wrist swings side to "
                             "side: 4 or more reversals",
                             lambda r, s=side: r[f"wrist_sway.{s}"] >= 4)]
            count = params.get("count")
            if count:  # GT: 2 * count reversals (+1 when the hand comes back to the middle)
                checks.append(Check(f"wave.{side}_count", f"{count} waves of the {side} hand",
                                    lambda r, s=side: r[f"wrist_sway.{s}"] // 2 == count))
        else:  # GT: 0.35-0.40 m above the head joint; a wave reaches 0.14 m at most
            checks.append(Check(f"raise_arms.{side}_up", f"the {side} wrist goes 0.2 m above "
                                "the head", lambda r, s=side: r[f"wrist_height.{s}"] > 0.2))
    if hand != "both":  # GT: the idle wrist stays 0.40 m or more below the head joint
        other = _other(hand)
        checks.append(Check(f"{family}.{other}_down", f"the {other} wrist stays 0.3 m below "
                            "the head", lambda r: r[f"wrist_height.{other}"] < -0.3))
    return checks


def _clap_checks(params: Mapping[str, Any]) -> list[Check]:
    checks = [Check("clap.meet", "the wrists come within 0.15 m of each other at least twice",
                    lambda r: r["hand_gap_minima"] >= 2)]
    checks += _count_check(params, "clap.count", "the hands meet {} times", "hand_gap_minima")
    return checks


def _strike_checks(family: str, params: Mapping[str, Any]) -> list[Check]:
    """punch, kick: the named limb thrusts forward, the other does not."""
    side = params.get("hand" if family == "punch" else "leg")
    sides = (side,) if side else SIDES
    count = params.get("count")
    if family == "punch":  # GT: the punching wrist reaches 0.45-0.54 m, the guard 0.18-0.26
        def hits(r: Readings, s: str) -> bool:
            return (r[f"wrist_reach.{s}"] > 0.38
                    and r[f"wrist_reach.{s}"] - r[f"wrist_reach.{_other(s)}"] > 0.12)
        checks = [Check("punch.reach", f"the {side or 'one'} wrist reaches over 0.38 m in front "
                        "of the pelvis, 0.12 m further than the other",
                        lambda r: any(hits(r, s) for s in sides))]
        if count and side:
            checks.append(Check("punch.count", f"{count} punches of the {side} hand",
                                lambda r: r[f"wrist_thrusts.{side}"] == count))
        return checks
    # kick. GT: the kicking ankle lifts 0.31-0.68 m and reaches 0.65-0.81 m forward.

    def kicks(r: Readings, s: str) -> bool:
        return (r[f"foot_lift.{s}"] > 0.25 and r[f"foot_reach.{s}"] > 0.45
                and r[f"foot_lift.{s}"] - r[f"foot_lift.{_other(s)}"] > 0.2)

    checks = [Check("kick.leg", f"the {side or 'one'} ankle lifts over 0.25 m (0.2 m more than "
                    "the other) and reaches 0.45 m in front of the pelvis",
                    lambda r: any(kicks(r, s) for s in sides))]
    if count and side:
        checks.append(Check("kick.count", f"{count} kicks of the {side} leg",
                            lambda r: r[f"foot_thrusts.{side}"] == count))
    return checks


def _posture_checks(family: str) -> list[Check]:
    """bow, stretch, stand."""
    if family == "bow":  # GT pitch 0.67-0.94 rad; squats and sits lean 0.46 at most
        return [Check("bow.pitch", "the torso leans over 0.55 rad (31 degrees) forward",
                      lambda r: r["torso_pitch"] > 0.55),
                Check("bow.hips_up", "the pelvis sinks less than 0.15 m",
                      lambda r: r["pelvis_drop"] < 0.15)]
    if family == "stretch":  # GT: wrists 0.40+ m above the head, leans 0.19-0.33 rad each way
        return [Check("stretch.arms_up", "both wrists go 0.2 m above the head",
                      lambda r: min(r["wrist_height.left"], r["wrist_height.right"]) > 0.2),
                Check("stretch.lean", "the torso leans 0.12 rad (7 degrees) to each side",
                      lambda r: min(r["torso_side_lean.left"], r["torso_side_lean.right"]) > 0.12)]
    # stand: nothing moves much. GT: the pelvis moves 0.16 m at most, leans back slightly.
    return [Check("stand.upright", "the torso leans less than 0.3 rad (17 degrees) forward",
                  lambda r: r["torso_pitch"] < 0.3),
            Check("stand.still", "the pelvis moves less than 0.3 m",
                  lambda r: np.hypot(r["forward_displacement"], r["lateral_displacement"]) < 0.3),
            Check("stand.facing", "turns less than 20 degrees",
                  lambda r: abs(r["heading_change"]) < np.radians(20)),
            Check("stand.level", "the pelvis stays within 0.1 m of its standing height",
                  lambda r: r["pelvis_drop"] < 0.1 and r["pelvis_rise"] < 0.1),
            Check("stand.feet_down", "neither ankle lifts over 0.08 m",
                  lambda r: max(r["foot_lift.left"], r["foot_lift.right"]) < 0.08),
            Check("stand.arms_down", "both wrists stay 0.3 m below the head",
                  lambda r: max(r["wrist_height.left"], r["wrist_height.right"]) < -0.3)]


def checks_for(action: Mapping[str, Any]) -> list[Check]:
    """The checks one action ({"family": ..., "params": {...}} as in labels.jsonl) must pass.

    A missing parameter drops the checks that need it (e.g. no "count": any number of claps).
    """
    family, params = action["family"], action.get("params") or {}
    if family in ("walk", "walk_backward", "jog", "run"):
        return _gait_checks(family, params)
    if family in ("turn", "spin", "circle"):
        return _turning_checks(family, params)
    if family == "side_step":
        return _side_step_checks(params)
    if family == "jump":
        return _jump_checks(params)
    if family == "hop":
        return _hop_checks(params)
    if family in ("squat", "sit_stand", "kneel"):
        return _lowering_checks(family, params)
    if family in ("wave", "raise_arms"):
        return _arm_checks(family, params)
    if family == "clap":
        return _clap_checks(params)
    if family in ("punch", "kick"):
        return _strike_checks(family, params)
    if family in ("bow", "stretch", "stand"):
        return _posture_checks(family)
    if family in EXTRA_CHECKS:
        return EXTRA_CHECKS[family](family, params)
    raise ValueError(f"no checks for action family {family!r}")


# ---------------------------------------------------------------------------- labels

def evaluate_label(joints: np.ndarray, label: Mapping[str, Any], margin: float = 0.0,
                   fps: float = FPS) -> list[tuple[str, bool]]:
    """(check name, passed) for every action of a labels.jsonl record.

    Each action of the sequence is judged inside its own window (`action_windows`); the
    concurrent upper-body action, if any, over the whole clip. Names of the checks of the
    i-th action are prefixed "i:" ("0:walk.forward"), the concurrent ones "+:".
    """
    joints = as_joints(joints)
    results: list[tuple[str, bool]] = []
    windows = action_windows(label, len(joints), margin, fps)
    for i, (action, (lo, hi)) in enumerate(zip(label["actions"], windows)):
        readings = read_all(joints[lo:hi])
        results += [(f"{i}:{c.name}", c(readings)) for c in checks_for(action)]
    if label.get("concurrent"):
        readings = read_all(joints)
        results += [(f"+:{c.name}", c(readings)) for c in checks_for(label["concurrent"])]
    return results


def evaluate_in_order(joints: np.ndarray, actions: Sequence[Mapping[str, Any]],
                      min_seconds: float = 1.0, step_seconds: float = 0.25,
                      fps: float = FPS) -> list[tuple[str, bool]]:
    """(check name, passed) for actions done one after another, at times the motion chooses.

    A hand-written prompt ("jumps, then squats") has no labelled timing, and cutting its clip
    into equal windows judges the timing as much as the actions: a squat begun 0.3 s before the
    middle fails. Here every cut of the clip into len(actions) consecutive windows of at least
    `min_seconds`, cuts on a grid of `step_seconds`, is tried, and the cut whose windows pass
    the most checks is reported (all of them, if any cut passes all). The order still counts:
    the i-th action must hold in the i-th window. Names as `evaluate_label`'s ("0:jump.up").
    """
    joints = as_joints(joints)
    n = len(joints)
    step = max(1, round(step_seconds * fps))
    shortest = max(2, round(min_seconds * fps))
    grid = range(shortest, n - shortest + 1, step)
    checks = [checks_for(a) for a in actions]
    readings: dict[tuple[int, int], dict[str, float]] = {}
    best: list[tuple[str, bool]] | None = None
    for cuts in itertools.combinations(grid, len(actions) - 1):
        bounds = (0, *cuts, n)
        if any(hi - lo < shortest for lo, hi in zip(bounds[:-1], bounds[1:])):
            continue
        results = []
        for i, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
            if (lo, hi) not in readings:
                readings[lo, hi] = read_all(joints[lo:hi])
            results += [(f"{i}:{c.name}", c(readings[lo, hi])) for c in checks[i]]
        if best is None or sum(p for _, p in results) > sum(p for _, p in best):
            best = results
            if all(p for _, p in best):
                break
    if best is None:
        raise ValueError(f"a clip of {n} frames is too short for {len(actions)} actions of at "
                         f"least {min_seconds} s each")
    return best


def passes(joints: np.ndarray, label: Mapping[str, Any], margin: float = 0.0) -> bool:
    """Whether a motion passes every check of its labels.jsonl record."""
    return all(ok for _, ok in evaluate_label(joints, label, margin))
