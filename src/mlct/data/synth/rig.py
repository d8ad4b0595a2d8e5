"""A posable body for the procedural benchmark: joint roles per skeleton, and pose -> positions.

A pose is a set of interpretable channels (hip flexion, knee flexion, spine bend, wrist targets
...). Positions are built bone by bone from unit directions times the skeleton's bone lengths,
so bone lengths are constant by construction. Arms are posed by two-bone IK from a wrist target,
which makes gestures (wave, clap, punch) easy to state. Only joint positions are produced: the
standard processing recovers rotations from positions by its own IK.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mlct.motion.skeleton import Skeleton

SIDES = ("left", "right")


@dataclass(frozen=True)
class Rig:
    """Which joints play which role in a skeleton (all indices are joint ids)."""

    skeleton: Skeleton
    spine: tuple[int, ...]  # bones of the spine, pelvis upwards (each bends a share)
    head: tuple[int, ...]  # neck / head bones
    chest: tuple[int, ...]  # bones that hang off the top of the spine before the arms
    shoulder: dict[str, int]
    elbow: dict[str, int]
    wrist: dict[str, int]
    hip: dict[str, int]
    knee: dict[str, int]
    ankle: dict[str, int]
    foot: dict[str, tuple[int, ...]]  # bones below the ankle
    scale: float  # skeleton units per metre

    @property
    def arm_length(self) -> float:
        """Shoulder to wrist, in metres."""
        lengths = self.skeleton.bone_lengths
        return float(lengths[self.elbow["left"]] + lengths[self.wrist["left"]]) / self.scale

    @property
    def shoulder_x(self) -> float:
        """Distance of a shoulder from the midline in the rest pose, in metres."""
        sk, joint, x = self.skeleton, self.shoulder["left"], 0.0
        while joint > 0:  # sum the rest offsets up to the root
            x += sk.rest_offsets[joint][0]
            joint = sk.parents[joint]
        return abs(x) / self.scale

    @property
    def floor_points(self) -> dict[int, float]:
        """Joints that touch the floor in floor poses (lying, sitting, hands down), each with
        the metres of flesh between the joint and the floor: the ground-contact solver puts a
        joint that far up when it is the lowest (lying on the back: pelvis and spine about
        0.1 m up, the back of the head 0.1 m, the heels 0.05 m as when standing)."""
        points = {0: 0.10, self.spine[0]: 0.11, self.spine[-1]: 0.10, self.head[-1]: 0.10}
        for side in SIDES:
            points.update({self.ankle[side]: 0.05, self.knee[side]: 0.05,
                           self.wrist[side]: 0.03, self.elbow[side]: 0.04,
                           **{joint: 0.0 for joint in self.foot[side]}})
        return points

    @property
    def contact_points(self) -> tuple[int, ...]:
        """Joints that may touch the ground: ankles, feet, knees."""
        points: list[int] = []
        for side in SIDES:
            points += [self.ankle[side], *self.foot[side], self.knee[side]]
        return tuple(points)


def make_rig(skeleton: Skeleton) -> Rig:
    """The rig of a known skeleton; an unknown one raises ValueError."""
    scale = 1000.0 if skeleton.unit == "mm" else 1.0
    if skeleton.name == "humanml3d":
        return Rig(skeleton, spine=(3, 6, 9), head=(12, 15), chest=(13, 14),
                   shoulder={"left": 16, "right": 17}, elbow={"left": 18, "right": 19},
                   wrist={"left": 20, "right": 21}, hip={"left": 1, "right": 2},
                   knee={"left": 4, "right": 5}, ankle={"left": 7, "right": 8},
                   foot={"left": (10,), "right": (11,)}, scale=scale)
    if skeleton.name == "kit":
        return Rig(skeleton, spine=(1, 2, 3), head=(4,), chest=(), shoulder={"left": 8, "right": 5},
                   elbow={"left": 9, "right": 6}, wrist={"left": 10, "right": 7},
                   hip={"left": 16, "right": 11}, knee={"left": 17, "right": 12},
                   ankle={"left": 18, "right": 13}, foot={"left": (19, 20), "right": (14, 15)},
                   scale=scale)
    raise ValueError(f"no synth rig for skeleton {skeleton.name!r}")


def rot_x(angle: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations about x; positive turns +y towards +z."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(angle), np.zeros_like(angle)
    return np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c, -s], -1),
                     np.stack([zero, s, c], -1)], -2)


def rot_y(angle: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations about y; positive turns +z towards +x (a turn to the left)."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(angle), np.zeros_like(angle)
    return np.stack([np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1),
                     np.stack([-s, zero, c], -1)], -2)


def rot_z(angle: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations about z; positive turns +x towards +y."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(angle), np.zeros_like(angle)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                     np.stack([zero, zero, one], -1)], -2)


def _apply(rotation: np.ndarray, vector: np.ndarray) -> np.ndarray:
    return np.einsum("tij,tj->ti", rotation, np.broadcast_to(vector, rotation.shape[:-1]))


def _two_bone(shoulder: np.ndarray, target: np.ndarray, upper: float, lower: float,
              pole: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elbow and wrist positions (T, 3) reaching for `target`, the elbow bent towards `pole`."""
    reach = target - shoulder
    dist = np.linalg.norm(reach, axis=-1, keepdims=True)
    u = reach / np.maximum(dist, 1e-9)
    d = np.clip(dist, abs(upper - lower) + 1e-6, (upper + lower) * 0.999)
    cos_a = np.clip((upper**2 + d**2 - lower**2) / (2 * upper * d), -1.0, 1.0)
    v = pole - np.sum(pole * u, -1, keepdims=True) * u  # pole direction orthogonal to the reach
    v_norm = np.linalg.norm(v, axis=-1, keepdims=True)
    # A pole parallel to the reach: fall back on any orthogonal direction.
    fallback = np.cross(u, np.array([1.0, 0.0, 0.0]))
    v = np.where(v_norm > 1e-6, v / np.maximum(v_norm, 1e-9),
                 fallback / np.maximum(np.linalg.norm(fallback, axis=-1, keepdims=True), 1e-9))
    elbow = shoulder + upper * (cos_a * u + np.sqrt(1 - cos_a**2) * v)
    wrist = shoulder + d * u
    return elbow, wrist


def pose_positions(rig: Rig, pose: dict[str, np.ndarray]) -> np.ndarray:
    """Joint positions (T, J, 3) with the pelvis at the origin, from pose channels.

    Channels (radians unless noted; arrays of length T; `_l` / `_r` = body side):
    yaw (heading, left-positive), hip_flex_*, hip_abd_* (outwards), knee_*, ankle_* (toes up),
    spine_bend (forward), spine_side (towards the left), spine_twist (left), head_nod,
    body_pitch (optional: the whole body tipped forward about the pelvis, for floor poses),
    wrist_* (T, 3): wrist target in metres relative to the shoulder, in the chest frame,
    pole_* (T, 3): where the elbow points, in the chest frame.
    """
    sk = rig.skeleton
    lengths = sk.bone_lengths
    rest = sk.rest_directions
    n_frames = len(pose["yaw"])
    pos = np.zeros((n_frames, sk.n_joints, 3))
    heading = rot_y(pose["yaw"])
    done = {0}

    def place(joint: int, rotation: np.ndarray) -> None:
        parent = sk.parents[joint]
        pos[:, joint] = pos[:, parent] + lengths[joint] * _apply(rotation, rest[joint])
        done.add(joint)

    # Spine: each bone takes a cumulative share of the bend, side lean and twist.
    shares = np.linspace(1.0 / len(rig.spine), 1.0, len(rig.spine))
    chest_rot = heading
    for joint, share in zip(rig.spine, shares):
        chest_rot = heading @ rot_y(pose["spine_twist"] * share) @ rot_x(pose["spine_bend"] * share) \
            @ rot_z(-pose["spine_side"] * share)
        place(joint, chest_rot)
    for joint in rig.head:
        place(joint, chest_rot @ rot_x(pose["head_nod"]))
    for joint in rig.chest:
        place(joint, chest_rot)

    for side, sign in (("left", 1.0), ("right", -1.0)):
        s = side[0]
        # Legs: flexion about x is additive down the chain; abduction swings the whole leg.
        leg = heading @ rot_z(sign * pose[f"hip_abd_{s}"])
        place(rig.hip[side], heading)
        place(rig.knee[side], leg @ rot_x(-pose[f"hip_flex_{s}"]))
        place(rig.ankle[side], leg @ rot_x(-pose[f"hip_flex_{s}"] + pose[f"knee_{s}"]))
        foot_rot = leg @ rot_x(-pose[f"hip_flex_{s}"] + pose[f"knee_{s}"] - pose[f"ankle_{s}"])
        for joint in rig.foot[side]:
            place(joint, foot_rot)
        # Arms: shoulder placed rigidly with the chest, elbow and wrist by two-bone IK.
        place(rig.shoulder[side], chest_rot)
        shoulder = pos[:, rig.shoulder[side]]
        target = shoulder + _apply(chest_rot, pose[f"wrist_{s}"] * rig.scale)
        pole = _apply(chest_rot, pose[f"pole_{s}"])
        elbow, wrist = _two_bone(shoulder, target, lengths[rig.elbow[side]],
                                 lengths[rig.wrist[side]], pole)
        pos[:, rig.elbow[side]] = elbow
        pos[:, rig.wrist[side]] = wrist
        done.update((rig.elbow[side], rig.wrist[side]))
    missing = set(range(sk.n_joints)) - done
    if missing:
        raise AssertionError(f"rig for {sk.name} leaves joints {sorted(missing)} unplaced")
    pitch = pose.get("body_pitch")
    if pitch is not None and np.any(pitch):
        # The whole body tips about the pelvis, forward-positive (lying on the back is -pi/2,
        # a push-up plank near +pi/2). Applied only where it is non-zero, so that the standing
        # families' positions are the very same floats they were before the channel existed.
        tip = heading @ rot_x(pitch) @ np.swapaxes(heading, -1, -2)
        pos = np.einsum("tij,tkj->tki", tip, pos)
    return pos
