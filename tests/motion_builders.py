"""Synthetic motions for the motion-core tests, built by forward kinematics (no data files)."""

from __future__ import annotations

import math

import numpy as np
import torch

from mlct.motion.kinematics import forward_kinematics
from mlct.motion.quaternion import qmul, quat_from_axis_angle
from mlct.motion.skeleton import Skeleton

Y_AXIS = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)


def yaw(angle: torch.Tensor | float) -> torch.Tensor:
    """Quaternion(s) of a rotation by `angle` about +y (turns +Z towards +X)."""
    return quat_from_axis_angle(Y_AXIS, torch.as_tensor(angle, dtype=torch.float64))


def leg_height(skeleton: Skeleton) -> float:
    """Height of the root above the floor when standing straight (hip to ankle to toe level)."""
    b = skeleton.bone_lengths
    ankle = skeleton.foot_left[0]
    knee = skeleton.parents[ankle]
    return float(b[knee] + b[ankle] + 0.1 * b[knee])


def random_motion(skeleton: Skeleton, n_frames: int, seed: int, *, amplitude: float = 0.25,
                  heading: tuple[float, float] = (0.3, 0.3 + 1.5 * math.pi),
                  speed: float = 1.0, scale: float = 1.0) -> np.ndarray:
    """(T, J, 3) float64: smooth random joint rotations, a root that walks along its heading
    (in skeleton units per second) and turns from heading[0] to heading[1] (radians)."""
    g = torch.Generator().manual_seed(seed)
    n = skeleton.n_joints
    t = torch.arange(n_frames, dtype=torch.float64) / skeleton.fps  # (T,) seconds
    axes = torch.randn(n, 3, generator=g, dtype=torch.float64)
    freq = 0.3 + 0.9 * torch.rand(n, generator=g, dtype=torch.float64)
    phase = 2 * math.pi * torch.rand(n, generator=g, dtype=torch.float64)
    angles = amplitude * torch.sin(2 * math.pi * freq * t[:, None] + phase)  # (T, J)
    local = quat_from_axis_angle(axes, angles)  # (T, J, 4)

    s = t / t[-1]
    head = heading[0] + (heading[1] - heading[0]) * (3 * s**2 - 2 * s**3)  # smooth start and stop
    wobble = quat_from_axis_angle(axes[0], 0.1 * torch.sin(2 * math.pi * freq[0] * t))
    local[:, 0] = qmul(yaw(head), wobble)

    step = speed / skeleton.fps * torch.stack([torch.sin(head), 0 * head, torch.cos(head)], -1)
    root = torch.cumsum(step, dim=0)  # (T, 3)
    root[:, 1] = leg_height(skeleton) * scale * (1 + 0.03 * torch.sin(2 * math.pi * 1.7 * t))
    offsets = torch.from_numpy(skeleton.rest_offsets) * scale
    return forward_kinematics(local, root, offsets, skeleton).numpy()


def square_pose_offsets(skeleton: Skeleton) -> np.ndarray:
    """(J, 3) the IK rest pose (raw directions * target lengths) turned to face +Z if needed.

    Its hip and shoulder lines are parallel, so the facing of the standard processing's IK
    (which, as the reference, subtracts the hip vector) equals the facing of its normalization
    (which adds it): goldens need no tolerance for the difference between the two.
    """
    offsets = skeleton.target_offsets.copy()
    r_hip, l_hip = skeleton.face_joints[:2]
    if offsets[r_hip, 0] > offsets[l_hip, 0]:  # right side on +x: the pose faces -Z
        offsets[:, 0] *= -1
    return offsets


def rigid_motion(skeleton: Skeleton, n_frames: int, *, heading0: float = 0.0,
                 turn_rate: float = 0.0, velocity: tuple[float, float] = (0.0, 0.0),
                 scale: float = 1.0, offsets: np.ndarray | None = None) -> np.ndarray:
    """(T, J, 3) a pose (default `square_pose_offsets`) moved rigidly: heading
    heading0 + turn_rate * t about the root (radians, rad/s), root xz velocity (units/s)."""
    t = torch.arange(n_frames, dtype=torch.float64) / skeleton.fps
    local = torch.zeros(n_frames, skeleton.n_joints, 4, dtype=torch.float64)
    local[..., 0] = 1.0
    local[:, 0] = yaw(heading0 + turn_rate * t)
    root = torch.zeros(n_frames, 3, dtype=torch.float64)
    root[:, 0] = 0.37 * scale + velocity[0] * t
    root[:, 1] = leg_height(skeleton) * scale
    root[:, 2] = -1.2 * scale + velocity[1] * t
    offsets = square_pose_offsets(skeleton) if offsets is None else offsets
    return forward_kinematics(local, root, torch.from_numpy(offsets) * scale, skeleton).numpy()
