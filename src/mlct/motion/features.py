"""The standard motion representation (HumanML3D 263-d, KIT-ML 251-d): joints <-> features.

`joints_to_features` is the HumanML3D processing step for step (process_file in
EricGuo5513/HumanML3D motion_representation.ipynb and text-to-motion scripts/motion_process.py),
computed in float64: uniform skeleton, floor, first root at the xz origin, facing +Z, foot
contacts, 6D rotations from smoothed IK, root angular / linear velocity, root height,
root-relative positions, local velocities. T frames in, T-1 feature frames out.

One deliberate deviation (docs/motion_representation.md): the root angular velocity is arcsin of
the y component of the relative root quaternion r[t+1] * r[t]^-1, and the reference takes it
without fixing the quaternion's sign. Its root quaternions have w >= 0, so where the heading
crosses +-180 degrees the relative quaternion comes out with w < 0 and the reference's angular
velocity has the wrong sign (-d/2 for a turn of d). We make w >= 0 before the arcsin; every other
frame is identical.

`recover_from_ric` inverts the root and ric groups: batched torch, differentiable, on the device
and dtype of its input (the joint loss J of the autoencoder).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from mlct.errors import MlctError
from mlct.motion.joints import features_to_joints, n_joints_for_dim  # noqa: F401 (numpy)
from mlct.motion.kinematics import facing_quaternion, inverse_kinematics, uniform_skeleton
from mlct.motion.quaternion import qinv, qmul, qrot, quat_to_cont6d
from mlct.motion.skeleton import FeatureLayout, Skeleton


@dataclass(frozen=True)
class MotionFeatures:
    """The result of `joints_to_features`."""

    features: np.ndarray  # (T-1, D) the standard feature vectors
    # (T, J, 3) normalized global positions (target skeleton, on the floor, facing +Z). The
    # standard new_joints files hold recover_from_ric(features) instead: the first T-1 of these.
    joints: np.ndarray


def arm_feature_columns(feature_dim: int) -> list[int]:
    """The feature columns of the arms' joints (motion/body_parts.py 'arms': the collars or
    shoulders and what hangs from them): their root-relative positions, rotations and local
    velocities."""
    from mlct.motion.body_parts import part_joints
    from mlct.motion.skeleton import skeleton_for_dim

    skeleton = skeleton_for_dim(feature_dim)
    groups = FeatureLayout(n_joints_for_dim(feature_dim)).groups
    columns = []
    for joint in part_joints("arms", skeleton):  # never the root, which has no ric/rotation
        columns += [groups["ric"].start + 3 * (joint - 1) + i for i in range(3)]
        columns += [groups["rotations"].start + 6 * (joint - 1) + i for i in range(6)]
        columns += [groups["local_velocity"].start + 3 * joint + i for i in range(3)]
    return sorted(columns)


def split_features(features: Tensor | np.ndarray,
                   layout: FeatureLayout) -> dict[str, Tensor | np.ndarray]:
    """The named feature groups of `layout.groups` as views of (..., D) features."""
    if features.shape[-1] != layout.dim:
        raise MlctError(f"features have {features.shape[-1]} values per frame, "
                        f"expected {layout.dim}")
    return {name: features[..., s] for name, s in layout.groups.items()}


def foot_contacts(joints: Tensor, skeleton: Skeleton) -> Tensor:
    """(T, J, 3) -> (T-1, 4) contacts [left ankle, left toe, right ankle, right toe] in {0, 1}.

    A foot joint is in contact when its squared displacement to the next frame is below the
    skeleton's threshold (0.002 m^2 HumanML3D, 0.05 mm^2 KIT), as the reference foot_detect.
    """
    feet = list(skeleton.foot_left) + list(skeleton.foot_right)
    step = joints[..., 1:, feet, :] - joints[..., :-1, feet, :]  # (T-1, 4, 3)
    return ((step**2).sum(dim=-1) < skeleton.contact_threshold).to(joints.dtype)


def place_on_floor_facing_z(joints: Tensor, skeleton: Skeleton) -> Tensor:
    """(T, J, 3): lowest joint on y = 0, first root at the xz origin, first frame facing +Z."""
    joints = joints - joints[..., 1].min() * joints.new_tensor([0.0, 1.0, 0.0])
    first = joints[0]  # (J, 3)
    joints = joints - first[0] * first.new_tensor([1.0, 0.0, 1.0])
    r_hip, l_hip, r_shoulder, l_shoulder = skeleton.face_joints
    # process_file unpacks the face joints correctly (unlike the IK, see inverse_kinematics).
    across = (first[r_hip] - first[l_hip]) + (first[r_shoulder] - first[l_shoulder])
    turn = facing_quaternion(across[None])[0]  # (4,)
    return qrot(turn, joints)


def _root_angular_velocity(r_rot: Tensor) -> Tensor:
    """(T, 4) root quaternions (yaw only) -> (T-1,) half-angle per frame about +y."""
    delta = qmul(r_rot[1:], qinv(r_rot[:-1]))  # (T-1, 4)
    # Deliberate deviation from the reference (module docstring): w >= 0 before the arcsin.
    delta = torch.where(delta[:, :1] < 0, -delta, delta)
    return torch.arcsin(delta[:, 2].clamp(-1.0, 1.0))


def _features(pos: Tensor, skeleton: Skeleton) -> Tensor:
    """(T, J, 3) normalized float64 positions -> (T-1, D) features (process_file after placing)."""
    n_frames, n_joints = pos.shape[:2]
    contacts = foot_contacts(pos, skeleton)  # (T-1, 4)

    quats = inverse_kinematics(pos, skeleton, smooth_forward=True)  # (T, J, 4)
    rot6d = quat_to_cont6d(quats[:, 1:])  # (T, J-1, 6)
    # Root rotations; r_rot[0] is the identity (the reference forces it), so the first angular
    # velocity also holds the small angle between the IK's facing and the normalization's.
    r_rot = quats[:, 0]  # (T, 4)

    # Root velocity in the frame of the later root rotation (reference: qrot(r_rot[1:], ...)).
    root_vel = qrot(r_rot[1:], pos[1:, 0] - pos[:-1, 0])  # (T-1, 3)
    root_ang_vel = _root_angular_velocity(r_rot)  # (T-1,)

    # ric: root-relative in xz, then turned so that the root faces +Z.
    ric = pos - pos[:, :1] * pos.new_tensor([1.0, 0.0, 1.0])
    ric = qrot(r_rot[:, None], ric)  # (T, J, 3)
    # Local velocity in the frame of the earlier root rotation (reference: r_rot[:-1]).
    local_vel = qrot(r_rot[:-1, None], pos[1:] - pos[:-1])  # (T-1, J, 3)

    t = n_frames - 1
    return torch.cat(
        [
            root_ang_vel[:, None],
            root_vel[:, [0, 2]],
            ric[:-1, 0, 1:2],  # root height
            ric[:-1, 1:].reshape(t, (n_joints - 1) * 3),
            rot6d[:-1].reshape(t, (n_joints - 1) * 6),
            local_vel.reshape(t, n_joints * 3),
            contacts,
        ],
        dim=-1,
    )


def joints_to_features(joints: np.ndarray, skeleton: Skeleton,
                       target_joints: np.ndarray | None = None,
                       dtype: type[np.floating] = np.float32) -> MotionFeatures:
    """(T, J, 3) global joint positions -> standard features (T-1, D) and normalized joints.

    `target_joints` (J, 3) is the target subject's first frame; by default the skeleton's bundled
    bone lengths are the target. Computed in float64, returned as `dtype`.
    """
    joints = np.asarray(joints)
    if joints.ndim != 3 or joints.shape[1:] != (skeleton.n_joints, 3):
        raise MlctError(f"joints must have shape (T, {skeleton.n_joints}, 3) for skeleton "
                        f"{skeleton.name!r}, got {joints.shape}")
    if joints.shape[0] < 2:
        raise MlctError(f"a motion needs at least 2 frames, got {joints.shape[0]}")
    if not np.isfinite(joints).all():
        raise MlctError("joints contain NaN or inf")
    pos = torch.from_numpy(joints.astype(np.float64))
    target = None if target_joints is None else np.asarray(target_joints, dtype=np.float64)
    pos = uniform_skeleton(pos, skeleton, target)
    pos = place_on_floor_facing_z(pos, skeleton)
    features = _features(pos, skeleton)
    if not torch.isfinite(features).all():
        raise MlctError("the motion has a degenerate first frame (zero-length legs or coincident "
                        "joints): its features are not finite")
    return MotionFeatures(features=features.numpy().astype(dtype), joints=pos.numpy().astype(dtype))


def root_half_angles(features: Tensor) -> Tensor:
    """(..., T, D) -> (..., T): the root's yaw half-angle at each frame, the running sum of the
    half-angle velocities before it (frame 0 faces +Z)."""
    rot_vel = features[..., 0]  # (..., T)
    return torch.cat([torch.zeros_like(rot_vel[..., :1]), torch.cumsum(rot_vel[..., :-1], dim=-1)],
                     dim=-1)


def recover_root_rot_pos(features: Tensor) -> tuple[Tensor, Tensor]:
    """(..., T, D) -> root yaw quaternions (..., T, 4) and root positions (..., T, 3).

    The yaw angle is the running sum of the half-angle velocities (frame 0 faces +Z); the root's
    xz is the running sum of the velocities turned back to the world frame; y is the root height.
    """
    half = root_half_angles(features)  # (..., T)
    zero = torch.zeros_like(half)
    r_rot = torch.stack([torch.cos(half), zero, torch.sin(half), zero], dim=-1)  # (..., T, 4)

    vel = features[..., :-1, 1:3]  # (..., T-1, 2) in the root frame of the later frame
    vel = torch.stack([vel[..., 0], torch.zeros_like(vel[..., 0]), vel[..., 1]], dim=-1)
    vel = torch.cat([vel.new_zeros(*vel.shape[:-2], 1, 3), vel], dim=-2)  # (..., T, 3); T=1 too
    xz = torch.cumsum(qrot(qinv(r_rot), vel), dim=-2)
    r_pos = torch.stack([xz[..., 0], features[..., 3], xz[..., 2]], dim=-1)  # (..., T, 3)
    return r_rot, r_pos


def recover_from_ric(features: Tensor, n_joints: int | None = None) -> Tensor:
    """(..., T, D) features -> (..., T, J, 3) global joint positions (from root and ric groups)."""
    n_joints = n_joints_for_dim(features.shape[-1]) if n_joints is None else n_joints
    r_rot, r_pos = recover_root_rot_pos(features)
    ric = features[..., 4:4 + (n_joints - 1) * 3]
    ric = ric.reshape(ric.shape[:-1] + (n_joints - 1, 3))  # (..., T, J-1, 3)
    world = qrot(qinv(r_rot)[..., None, :], ric)
    ground = torch.stack([r_pos[..., 0], torch.zeros_like(r_pos[..., 1]), r_pos[..., 2]], dim=-1)
    world = world + ground[..., None, :]  # the root's x, z (no tensor from the host: graph-safe)
    return torch.cat([r_pos[..., None, :], world], dim=-2)
