"""Motion-space corrections that make controls exact while keeping the motion smooth.

After the pace (control/pace.py), the candidates or guidance (control/controlled.py) have
brought the motion near its controls, these close the remaining gap on the joints (T, J, 3), in
numpy:
- a root path: the xz error at the waypoints is interpolated with a monotone cubic (PCHIP: C1,
  no overshoot between waypoints) and added to every joint, so the correction is as smooth and
  low-frequency as the waypoints are sparse; a heading the same way, as a turn about the root;
- keyframes: each constrained joint's error at its key frame is spread over the frames around
  it (REACH_SECONDS each side, PCHIP through zero outside), so a pinned pose is met exactly and
  the motion eases into and out of it; a single joint (an end effector) first moves its limb by
  FABRIK (Aristidou & Lasenby 2011), which keeps the limb's bone lengths, and its descendants
  with it;
- body-part edits: the kept joints are copied exactly; each edited joint is re-attached to its
  parent with the kept motion's bone length, pointing where the new motion's bone points (turned
  into the kept body's facing);
- the floor (`on_floor`): a motion whose lowest joint is under the floor is raised onto it, as
  the data's processing stands every clip (HumanML3D's lowest joint at y = 0).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from scipy.interpolate import PchipInterpolator

from mlct.motion.foot_lock import two_bone_ik
from mlct.motion.skeleton import Skeleton

REACH_SECONDS = 0.75  # how far a keyframe's correction spreads each side (15 frames at 20 fps)
FABRIK_ITERATIONS = 20
CHAIN_BONES = 3  # an end effector moves itself and up to this many bones above it


def turn_y(points: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Rotate (..., 3) points about +y by angle (radians; + turns +Z towards +X)."""
    cos, sin = np.cos(angle), np.sin(angle)
    x, z = points[..., 0], points[..., 2]
    return np.stack([cos * x + sin * z, points[..., 1], -sin * x + cos * z], axis=-1)


def hip_heading(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(..., J, 3) -> (...,) facing angle from the hips alone (0 facing +Z), for edits that
    change the shoulders."""
    r_hip, l_hip = skeleton.face_joints[:2]
    across = joints[..., r_hip, :] - joints[..., l_hip, :]
    return np.arctan2(across[..., 2], -across[..., 0])


def offset_curve(frames: np.ndarray, values: np.ndarray, length: int,
                 reach: int | None = None) -> np.ndarray:
    """(length, C) offsets through values (K, C) at frames (K,): PCHIP between them; beyond the
    first and last held constant (reach None) or eased to zero `reach` frames away, also in
    gaps wider than 2 reach (a keyframe's correction stays local)."""
    order = np.argsort(frames)
    frames, values = np.asarray(frames, dtype=np.float64)[order], values[order]
    if reach is not None:
        # zero knots in pairs one frame apart: PCHIP's slope is 0 at a knot next to a flat
        # interval, so a correction eases in and out with zero velocity (no kink)
        zero = np.zeros_like(values[0])
        knots, vals = [frames[0] - reach - 1, frames[0] - reach], [zero, zero]
        for k in range(len(frames)):
            knots.append(frames[k])
            vals.append(values[k])
            if k + 1 < len(frames) and frames[k + 1] - frames[k] > 2 * reach:
                knots += [frames[k] + reach, frames[k + 1] - reach]
                vals += [zero, zero]
        knots += [frames[-1] + reach, frames[-1] + reach + 1]
        vals += [zero, zero]
        frames, values = np.array(knots), np.stack(vals)
    t = np.arange(length, dtype=np.float64)
    if len(frames) == 1:
        return np.repeat(values[:1], length, axis=0)
    curve = PchipInterpolator(frames, values, axis=0, extrapolate=False)(t)
    curve[t < frames[0]] = values[0]
    curve[t > frames[-1]] = values[-1]
    return curve


FLOOR_LIFT = 0.05  # m: the most on_floor raises a motion (a deeper dip is a glitch, not a floor)


def on_floor(joints: np.ndarray) -> np.ndarray:
    """The motion raised so that its lowest joint is on the floor (y = 0), by at most
    FLOOR_LIFT; one that is above it is left. The bundled model's walks sink 1.5 cm below it at
    their lowest (the data's clips: 0.1 cm), and the toes skimming under GMD's 5 cm then count
    as skating (bench/control.py --speeds; docs/control.md)."""
    lift = min(max(-float(np.min(joints[..., 1])), 0.0), FLOOR_LIFT)
    out = np.array(joints, dtype=np.float64, copy=True)
    out[..., 1] += lift
    return out


def fit_path(joints: np.ndarray, frames: np.ndarray, xz: np.ndarray) -> np.ndarray:
    """Move the body so that the root's xz is xz (K, 2) at frames (K,), smoothly between."""
    error = xz - joints[frames, 0][:, [0, 2]]  # (K, 2)
    shift = offset_curve(frames, error, len(joints))  # (T, 2)
    out = joints.copy()
    out[..., 0] += shift[:, None, 0]
    out[..., 2] += shift[:, None, 1]
    return out


def fit_heading(joints: np.ndarray, frames: np.ndarray, angles: np.ndarray,
                skeleton: Skeleton) -> np.ndarray:
    """Turn the body about its root so that it faces angles (K,) at frames, smoothly between."""
    from mlct.generate.control.facing import heading

    now = np.unwrap(heading(joints, skeleton))[frames]
    error = np.angle(np.exp(1j * (angles - now)))  # wrapped to (-pi, pi]
    turn = offset_curve(frames, error[:, None], len(joints))[:, 0]  # (T,)
    root = joints[:, :1] * np.array([1.0, 0.0, 1.0])
    return turn_y(joints - root, turn[:, None]) + root


def fabrik(chain: np.ndarray, target: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Positions (n, 3) of a chain whose first joint stays and whose last reaches towards
    target, bone lengths (n-1,) kept (FABRIK). Out of reach: the chain points at the target."""
    out = chain.copy()
    base = chain[0].copy()
    if np.linalg.norm(target - base) >= lengths.sum():
        for i in range(1, len(out)):
            step = target - out[i - 1]
            out[i] = out[i - 1] + lengths[i - 1] * step / max(np.linalg.norm(step), 1e-9)
        return out
    for _ in range(FABRIK_ITERATIONS):
        out[-1] = target
        for i in range(len(out) - 2, -1, -1):  # backward: from the effector to the base
            step = out[i] - out[i + 1]
            out[i] = out[i + 1] + lengths[i] * step / max(np.linalg.norm(step), 1e-9)
        out[0] = base
        for i in range(1, len(out)):  # forward: from the base to the effector
            step = out[i] - out[i - 1]
            out[i] = out[i - 1] + lengths[i - 1] * step / max(np.linalg.norm(step), 1e-9)
        if np.linalg.norm(out[-1] - target) < 1e-5:
            break
    return out


def reach_pose(pose: np.ndarray, targets: Mapping[int, Sequence[float]],
               skeleton: Skeleton) -> np.ndarray:
    """(J, 3) pose moved to meet targets {joint: xyz}: a whole pose when every joint is given,
    else each joint by FABRIK on its chain of CHAIN_BONES bones, descendants carried along."""
    if len(targets) == skeleton.n_joints:
        return np.array([targets[j] for j in range(skeleton.n_joints)], dtype=np.float64)
    out = pose.copy()
    for joint, target in targets.items():
        goal = np.asarray(target, dtype=np.float64)
        chain = [joint]
        while len(chain) <= CHAIN_BONES and skeleton.parents[chain[-1]] >= 0:
            chain.append(skeleton.parents[chain[-1]])
        chain.reverse()  # base first
        before = out[joint].copy()
        if len(chain) == 1:  # the root: the whole body follows it
            out += goal - before
            continue
        lengths = np.linalg.norm(np.diff(out[chain], axis=0), axis=-1)
        out[chain] = fabrik(out[chain], goal, lengths)
        out[list(skeleton.descendants(joint))] += out[joint] - before
    return out


def fit_keyframes(joints: np.ndarray, keys: Sequence[tuple[int, Mapping[int, Sequence[float]]]],
                  skeleton: Skeleton, reach: int) -> np.ndarray:
    """Meet every keyframe (frame, {joint: xyz}) exactly, easing each joint's correction in and
    out over `reach` frames."""
    by_frame: dict[int, dict[int, Sequence[float]]] = {}
    for frame, targets in keys:
        by_frame.setdefault(int(frame), {}).update(targets)
    # per joint: the corrections at the frames that move it
    moved: dict[int, tuple[list[int], list[np.ndarray]]] = {}
    for frame, targets in sorted(by_frame.items()):
        delta = reach_pose(joints[frame], targets, skeleton) - joints[frame]  # (J, 3)
        for j in np.flatnonzero(np.abs(delta).max(axis=-1) > 0):
            moved.setdefault(int(j), ([], []))
            moved[int(j)][0].append(frame)
            moved[int(j)][1].append(delta[j])
    out = joints.copy()
    for j, (frames, deltas) in moved.items():
        out[:, j] += offset_curve(np.array(frames), np.stack(deltas), len(joints), reach)
    # Joints moved apart by different offsets stretch their bones between the keys: give every
    # bone its length back, eased like the offsets from the motion's own to the key pose's.
    own = bone_lengths(joints, skeleton)  # (T, J)
    key_frames = np.array(sorted(by_frame))
    at_keys = bone_lengths(out[key_frames], skeleton)
    lengths = own + offset_curve(key_frames, at_keys - own[key_frames], len(joints), reach)
    return with_bone_lengths(out, lengths, skeleton)


def bone_lengths(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(..., J, 3) -> (..., J): each joint's distance to its parent (0 for the root)."""
    parents = [max(p, 0) for p in skeleton.parents]
    return np.linalg.norm(joints - joints[..., parents, :], axis=-1)


def with_bone_lengths(joints: np.ndarray, lengths: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, J, 3) re-built from the root outwards: each bone points as in joints, with the length
    lengths (T, J) gives it."""
    out = joints.copy()
    for j in range(1, skeleton.n_joints):  # parents come first in the skeleton's order
        parent = skeleton.parents[j]
        bone = joints[:, j] - joints[:, parent]
        norm = np.maximum(np.linalg.norm(bone, axis=-1, keepdims=True), 1e-9)
        out[:, j] = out[:, parent] + lengths[:, j:j + 1] * bone / norm
    return out


def lock_feet(joints: np.ndarray, before: np.ndarray, skeleton: Skeleton,
              keyed: Mapping[int, set[int]] | None = None, fade: int = 3) -> np.ndarray:
    """Feet that stood on the floor in `before` (the motion as the model made it) held still in
    `joints` (the corrected motion) for as long as they stood, by moving the ankle and toe and
    bending the knee (two-bone IK); eased over `fade` frames at each end of a stance.
    keyed: {frame: joints a keyframe pins there}: a leg with a pinned joint is not moved at
    that frame, and a stance ends there."""
    keyed = keyed or {}
    out = joints.copy()
    floor = before[..., 1].min()
    for ankle, toe in (skeleton.foot_left, skeleton.foot_right):
        knee, hip = skeleton.parents[ankle], skeleton.parents[skeleton.parents[ankle]]
        step = np.linalg.norm(np.diff(before[:, toe, [0, 2]], axis=0), axis=-1)  # (T-1,)
        low = before[:, toe, 1] - floor < STANCE_HEIGHT
        stance = np.concatenate([[False], (step < STANCE_STEP) & low[1:] & low[:-1]])
        stance[0] = stance[1] if len(stance) > 1 else False
        # a frame whose leg a keyframe pins is no stance: the key decides where that foot is
        leg = {hip, knee, ankle, toe}
        pinned = [f for f, js in keyed.items() if leg & set(js) and 0 <= f < len(joints)]
        stance[pinned] = False
        shift = np.zeros((len(joints), 3))
        weight = np.zeros(len(joints))
        t = 0
        while t < len(joints):
            if not stance[t]:
                t += 1
                continue
            end = t
            while end + 1 < len(joints) and stance[end + 1]:
                end += 1
            hold = out[t:end + 1, toe, [0, 2]].mean(axis=0)  # where this stance plants the foot
            # The ease in and out lasts as long as it takes to move the foot RELEASE_STEP a frame
            # at most: a foot held far from the corrected motion, let go over `fade` frames,
            # snapped 0.36 m in one frame on a corrected walk.
            ease = [max(fade, int(np.ceil(np.linalg.norm(hold - out[f, toe, [0, 2]])
                                          / RELEASE_STEP))) for f in (t, end)]
            for f in range(max(0, t - ease[0]), min(len(joints), end + ease[1] + 1)):
                inside = min(f, end) if f > end else max(f, t)
                span = ease[1] if f > end else ease[0]
                w = 1.0 if t <= f <= end else 1.0 - abs(f - inside) / (span + 1)
                # summed, not the larger weight's alone: where one stance's ease-out meets the
                # next one's ease-in, switching between their shifts was a pop
                weight[f] += w
                shift[f, [0, 2]] += w * (hold - out[inside, toe, [0, 2]])
            t = end + 1
        shift /= np.maximum(weight, 1.0)[:, None]  # overlapping stances: their weighted mean
        weight = np.minimum(weight, 1.0)
        if pinned:  # a keyframe's leg stays exactly where it pins it, and the lock eases in
            near = np.abs(np.arange(len(joints))[:, None] - np.array(pinned)[None]).min(axis=1)
            eased = np.minimum(weight, near / (fade + 1))
            shift *= (eased / np.maximum(weight, 1e-12))[:, None]
            weight = eased
        moved = weight > 0
        if not moved.any():
            continue
        goal = out[moved, ankle] + shift[moved]
        new_knee, new_ankle = two_bone_ik(out[moved, hip], out[moved, knee], out[moved, ankle],
                                          goal)
        carried = new_ankle - out[moved, ankle]
        out[moved, knee], out[moved, ankle] = new_knee, new_ankle
        out[moved, toe] += carried
    return out


# A toe this near the motion's floor and this slow (0.8 m/s at 20 fps) stands. Measured with
# bench/control.py's 60 test motions, best of 4 + correction (path and keyframe tasks): at
# 8 cm and 3 / 4 / 5 cm per frame the skating ratio is 0.158 / 0.140 / 0.127 and the read-out
# pass rate 0.433 / 0.425 / 0.417 (the data's skating 0.145; plain generation's 0.178). On the
# path task alone at 2 cm/frame, 5 cm: 0.22. 4 cm/frame holds the model's own slow slides too.
STANCE_HEIGHT = 0.08  # m
STANCE_STEP = 0.04  # m per frame
RELEASE_STEP = 0.05  # m per frame: the fastest a lock moves the foot as it eases in or out


def reattach(made: np.ndarray, kept: np.ndarray, parts: Sequence[int],
             skeleton: Skeleton) -> np.ndarray:
    """The kept motion (T, J, 3) with the joints `parts` taken from `made`: each edited bone
    keeps the kept motion's length and points as made's does, turned from made's facing (hips)
    into kept's."""
    out = kept.copy()
    turn = hip_heading(kept, skeleton) - hip_heading(made, skeleton)  # (T,)
    for j in sorted(parts):  # parents before children: the skeleton's joint order
        parent = skeleton.parents[j]
        bone = turn_y(made[:, j] - made[:, parent], turn)
        length = np.linalg.norm(kept[:, j] - kept[:, parent], axis=-1, keepdims=True)
        out[:, j] = out[:, parent] + length * bone / np.maximum(
            np.linalg.norm(bone, axis=-1, keepdims=True), 1e-9)
    return out
