"""Analytic first guesses of the G1's leg and arm angles, from the directions of the limbs they
should follow; the least-squares solve (chain.py) then takes up what they leave (the links'
small offsets, the exact targets, the limits).

A hip or a shoulder is three hinges, pitch (y), roll (x), yaw (z), then a knee or elbow about
y. For an arm, the upper arm's whole frame is known from the upper arm and the forearm: its
z runs up the upper arm and its y is the elbow's hinge, perpendicular to both; that frame split
into pitch, roll, yaw (y x z order), of its two splittings the one within the limits. A leg
takes its pitch and roll from the thigh and its yaw from the foot's heading.
"""

from __future__ import annotations

import numpy as np

from mlct.motion.robots import g1
from mlct.motion.robots.chain import Chain, axis_rotation

CHAIN = Chain(g1.BODIES)
TWO_PI = 2 * np.pi


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _rotate(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("tij,tj->ti", m, v)


def _excess(value: np.ndarray, k: int) -> np.ndarray:
    return np.maximum(0, np.maximum(CHAIN.lower[k] - value, value - CHAIN.upper[k]))


def _choose(candidates: list[tuple[np.ndarray, ...]], joints: list[int],
            weights: tuple = (), rank: int = 0) -> list[np.ndarray]:
    """Per frame, the candidate angle tuple that leaves its joints' limits least (each
    joint's excess times its weight, 1 unless given); rank 1, 2, ...: the next best."""
    weights = tuple(weights) + (1.0,) * (len(joints) - len(weights))
    cost = np.stack([sum(w * _excess(a, k) for a, k, w in zip(c, joints, weights))
                     for c in candidates])
    best, frames = np.argsort(cost, axis=0, kind="stable")[rank], np.arange(cost.shape[1])
    return [np.stack([c[i] for c in candidates])[best, frames] for i in range(len(joints))]


def _wraps(angles: tuple[np.ndarray, ...]) -> list[tuple[np.ndarray, ...]]:
    """The same rotation with the first and last angles turned by 0 or +-2 pi."""
    return [(angles[0] + a, *angles[1:-1], angles[-1] + b)
            for a in (0, -TWO_PI, TWO_PI) for b in (0, -TWO_PI, TWO_PI)]


def _yxz(m: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Both splittings (pitch, roll, yaw) of m = Ry(pitch) Rx(roll) Rz(yaw), with their 2 pi
    turns."""
    roll = np.arcsin(np.clip(-m[:, 1, 2], -1, 1))
    pitch = np.arctan2(m[:, 0, 2], m[:, 2, 2])
    yaw = np.arctan2(m[:, 1, 0], m[:, 1, 1])
    return _wraps((pitch, roll, yaw)) + _wraps((pitch + np.pi, np.pi - roll, yaw + np.pi))


def leg_start(q: np.ndarray, hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray,
              foot_rot: np.ndarray, pelvis: np.ndarray, side: str) -> None:
    """Hip pitch / roll / yaw and knee into q (T, n) from the thigh, the shin and the foot's
    target frame (world, (T, 3) and (T, 3, 3)), the pelvis's rotation (T, 3, 3)."""
    to_pelvis = np.swapaxes(pelvis, 1, 2)
    d = _unit(_rotate(to_pelvis, knee - hip))
    roll = np.arcsin(np.clip(d[:, 1], -1, 1))
    pitch = np.arctan2(-d[:, 0], -d[:, 2])
    names = [f"{side}_hip_pitch_joint", f"{side}_hip_roll_joint"]
    candidates = [(pitch + turn, roll) for turn in (0, -TWO_PI, TWO_PI)] + [
        (pitch + turn, flip - roll) for turn in (np.pi, -np.pi) for flip in (np.pi, -np.pi)]
    pitch, roll = _choose(candidates, [CHAIN.joint(n) for n in names])
    thigh = np.swapaxes(axis_rotation(1, pitch) @ axis_rotation(0, roll), 1, 2)
    forward = _rotate(thigh @ to_pelvis, foot_rot[:, :, 0])
    bend = np.arccos(np.clip(np.sum(_unit(knee - hip) * _unit(ankle - knee), -1), -1, 1))
    for name, value in (("hip_pitch", pitch), ("hip_roll", roll),
                        ("hip_yaw", np.arctan2(forward[:, 1], forward[:, 0])), ("knee", bend)):
        q[:, CHAIN.joint(f"{side}_{name}_joint")] = value


def arm_start(q: np.ndarray, torso: np.ndarray, shoulder: np.ndarray, elbow: np.ndarray,
              wrist: np.ndarray, side: str, rank: int = 0, own_hinge: bool = True) -> None:
    """Shoulder pitch / roll / yaw and elbow into q (T, n) from the shoulder, elbow and wrist
    targets (world, (T, 3)) and the torso's rotation (T, 3, 3); rank 1, 2, ...: the splitting
    next nearest the limits, another start for the solver where the nearest one is stuck.
    own_hinge False: the elbow's plane is not the motion's but the one the upper arm's pitch
    and roll alone give (no twist), a start that keeps the yaw off its limits."""
    to_torso = np.swapaxes(torso, 1, 2)
    upper = _unit(_rotate(to_torso, elbow - shoulder))
    fore = _unit(_rotate(to_torso, wrist - elbow))
    # The elbow flexes about the upper-arm link's -y: rotating the upper arm's direction towards
    # the forearm's is a turn about upper x fore. A near-straight arm has no such plane: the
    # hinge then leans to the torso's left-right axis (the G1's rest hinge).
    normal = np.cross(upper, fore)
    untwisted = axis_rotation(1, np.arctan2(-upper[:, 0], -upper[:, 2])) @ axis_rotation(
        0, np.arcsin(np.clip(upper[:, 1], -1, 1)))
    rest = -untwisted[:, :, 1]  # the hinge of the upper arm turned by pitch and roll alone
    # the rest hinge weighs in under ~6 degrees of bend
    hinge = _unit(normal + 0.1 * rest) if own_hinge else rest
    z = -upper
    y = _unit(-hinge - z * np.sum(-hinge * z, -1, keepdims=True))
    frame = np.stack([np.cross(y, z), y, z], -1)  # the upper-arm link's frame in the torso's
    # The pitch link's fixed turn (about x, tiny elsewhere) is undone before splitting, the
    # roll link's (about x) added to the roll.
    pitch_body, roll_body = (g1.BODIES[CHAIN.joint_body[CHAIN.joint(f"{side}_shoulder_{a}"
                                                                    "_joint")]]
                             for a in ("pitch", "roll"))
    fixed_pitch = CHAIN.fixed[CHAIN.body(pitch_body.name)]
    tilt = 2 * np.arctan2(roll_body.quat[1], roll_body.quat[0])
    local = np.einsum("tji,tj->ti", frame, fore)  # the forearm in the upper-arm link's frame
    bend = np.arctan2(-local[:, 2], local[:, 0])
    # Yaw past its limit only turns the elbow's plane about the upper arm: it moves the hand
    # little when the arm is nearly straight (by the bend's sine), so there it costs less than
    # a pitch or roll past theirs.
    names = [f"{side}_shoulder_{a}_joint" for a in ("pitch", "roll", "yaw")]
    pitch, roll, yaw = _choose([(p, r - tilt, w) for p, r, w in _yxz(fixed_pitch.T @ frame)],
                               [CHAIN.joint(n) for n in names], (1.0, 1.0, np.abs(np.cos(bend))),
                               rank)
    for name, value in zip(names + [f"{side}_elbow_joint"], (pitch, roll, yaw, bend)):
        q[:, CHAIN.joint(name)] = value
