"""Forward and inverse kinematics on a Skeleton, in the HumanML3D convention.

Local rotations are indexed by the child joint of a bone: the rotation stored at joint j turns the
bone (parent(j) -> j). Along every kinematic chain the global rotation starts from the root
quaternion and accumulates down the chain; a chain that starts at a non-root joint (the arms start
at the spine) starts again from the root quaternion, as in the reference Skeleton. FK loops over
the chains, IK treats all bones at once; both are vectorized over time and batch.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from mlct.motion.quaternion import cont6d_to_matrix, qbetween, qinv, qmul, qrot
from mlct.motion.skeleton import Skeleton

# Standard deviation (frames) of the Gaussian that smooths the facing direction in the standard
# processing (reference Skeleton.inverse_kinematics_np, smooth_forward=True).
FORWARD_SMOOTHING_SIGMA = 20.0


def _like(x: Tensor | np.ndarray, ref: Tensor) -> Tensor:
    """x as a tensor with the dtype and device of `ref`."""
    return torch.as_tensor(x, dtype=ref.dtype, device=ref.device)


def _unit(v: Tensor) -> Tensor:
    return v / v.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(v.dtype).tiny)


def forward_kinematics(local_quats: Tensor, root_pos: Tensor, offsets: Tensor | np.ndarray,
                       skeleton: Skeleton) -> Tensor:
    """Joint positions (..., J, 3) from local quaternions (..., J, 4), the root position (..., 3)
    and bone offsets (J, 3) or (..., J, 3) (rest-pose vectors parent -> joint)."""
    offsets = _like(offsets, local_quats)
    joints: list[Tensor | None] = [None] * skeleton.n_joints
    joints[0] = root_pos.expand(local_quats.shape[:-2] + (3,))
    for chain in skeleton.kinematic_chain:
        rot = local_quats[..., 0, :]  # (..., 4)
        for parent, child in zip(chain[:-1], chain[1:]):
            rot = qmul(rot, local_quats[..., child, :])
            joints[child] = joints[parent] + qrot(rot, offsets[..., child, :])
    return torch.stack(joints, dim=-2)  # type: ignore[arg-type]


def forward_kinematics_cont6d(local_cont6d: Tensor, root_pos: Tensor,
                              offsets: Tensor | np.ndarray, skeleton: Skeleton) -> Tensor:
    """As `forward_kinematics`, with local rotations in 6D (..., J, 6)."""
    offsets = _like(offsets, local_cont6d)
    mats = cont6d_to_matrix(local_cont6d)  # (..., J, 3, 3)
    joints: list[Tensor | None] = [None] * skeleton.n_joints
    joints[0] = root_pos.expand(local_cont6d.shape[:-2] + (3,))
    for chain in skeleton.kinematic_chain:
        rot = mats[..., 0, :, :]
        for parent, child in zip(chain[:-1], chain[1:]):
            rot = rot @ mats[..., child, :, :]
            joints[child] = joints[parent] + (rot @ offsets[..., child, :, None])[..., 0]
    return torch.stack(joints, dim=-2)  # type: ignore[arg-type]


def bone_lengths(joints: Tensor, skeleton: Skeleton) -> Tensor:
    """(..., J, 3) -> (..., J): length of the bone ending at each joint (0 for the root)."""
    parents = list(skeleton.parents)
    parents[0] = 0  # root: a zero-length bone to itself
    return (joints - joints[..., parents, :]).norm(dim=-1)


def offsets_from_joints(joints: Tensor, skeleton: Skeleton) -> Tensor:
    """(..., J, 3) -> (..., J, 3) IK rest-pose offsets: raw direction * measured bone length."""
    raw = _like(skeleton.raw_offsets, joints)
    return raw * bone_lengths(joints, skeleton)[..., None]


def facing_quaternion(across: Tensor, smooth: bool = False) -> Tensor:
    """(..., T, 3) body right-pointing vectors -> (..., T, 4) yaw that turns the facing to +Z.

    forward = y x across, optionally smoothed over time (axis -2) like the reference.
    """
    across = _unit(across)
    up = across.new_tensor([0.0, 1.0, 0.0])
    forward = torch.cross(up.expand_as(across), across, dim=-1)
    if smooth:
        # scipy, not torch: the standard processing uses exactly this filter (not differentiable).
        # Imported here: scipy.ndimage costs 0.1-0.3 s, and generating a motion never smooths.
        from scipy.ndimage import gaussian_filter1d

        smoothed = gaussian_filter1d(forward.detach().cpu().numpy(), FORWARD_SMOOTHING_SIGMA,
                                     axis=-2, mode="nearest")
        forward = _like(smoothed, forward)
    forward = _unit(forward)
    return qbetween(forward, forward.new_tensor([0.0, 0.0, 1.0]).expand_as(forward))


def inverse_kinematics(joints: Tensor, skeleton: Skeleton, smooth_forward: bool = False) -> Tensor:
    """(..., T, J, 3) joint positions -> (..., T, J, 4) local quaternions w.r.t. the raw offsets.

    Step for step the reference Skeleton.inverse_kinematics_np: the root quaternion turns the
    (optionally smoothed) facing direction to +Z, frame 0's root quaternion is forced to identity,
    and each bone's local rotation is (global rotation of its parent in the chain)^-1 times the
    shortest rotation from its raw offset direction to its measured direction.
    """
    r_hip, l_hip, r_shoulder, l_shoulder = skeleton.face_joints
    # The reference unpacks face_joint_idx as (l_hip, r_hip, sdr_r, sdr_l), so its hip vector
    # points from the right hip to the LEFT one while its shoulder vector points to the right:
    # shoulder vector minus hip vector. Shoulders are wider than hips on both skeletons, so this
    # still points right. We keep the quirk: the distributed features (6D rotations, root
    # rotation) were computed with it.
    across = (joints[..., l_hip, :] - joints[..., r_hip, :]) + (
        joints[..., r_shoulder, :] - joints[..., l_shoulder, :])  # (..., T, 3)
    root = facing_quaternion(across, smooth=smooth_forward)  # (..., T, 4)
    identity = root.new_tensor([1.0, 0.0, 0.0, 0.0]).expand_as(root[..., :1, :])
    root = torch.cat([identity, root[..., 1:, :]], dim=-2)

    # All bones at once. A bone's global rotation is the shortest turn from its raw offset to its
    # measured direction; its local rotation is relative to the previous bone of its chain, or to
    # the root quaternion for a chain's first bone (the reference restarts each chain there).
    parents = list(skeleton.parents[1:])
    bones = _unit(joints[..., 1:, :] - joints[..., parents, :])  # (..., T, J-1, 3)
    raw = _like(skeleton.raw_offsets[1:], joints).expand_as(bones)
    global_rot = torch.cat([root[..., None, :], qbetween(raw, bones)], dim=-2)  # (..., T, J, 4)
    first_bones = {chain[1] for chain in skeleton.kinematic_chain}
    previous = [0 if j in first_bones else skeleton.parents[j] for j in range(1, skeleton.n_joints)]
    local = qmul(qinv(global_rot[..., previous, :]), global_rot[..., 1:, :])
    return torch.cat([root[..., None, :], local], dim=-2)


def uniform_skeleton(positions: Tensor, skeleton: Skeleton,
                     target_joints: Tensor | np.ndarray | None = None) -> Tensor:
    """Retarget (T, J, 3) positions to the target bone lengths (reference uniform_skeleton).

    The root trajectory is scaled by the ratio of the lower-leg lengths (skeleton.leg_joints) of
    target and source first frame; the pose is carried over by IK (unsmoothed) and FK with the
    target offsets. `target_joints` (J, 3), e.g. the first frame of the real target subject,
    replaces the skeleton's bundled bone lengths.
    """
    src = offsets_from_joints(positions[..., 0, :, :], skeleton)  # (J, 3)
    if target_joints is None:
        tgt = _like(skeleton.target_offsets, positions)
    else:
        tgt = offsets_from_joints(_like(target_joints, positions), skeleton)
    # The reference takes |offset|.max() per leg bone; raw offsets are axis-aligned unit vectors,
    # so that is the bone length.
    legs = list(skeleton.leg_joints)
    scale = tgt[..., legs, :].norm(dim=-1).sum(-1) / src[..., legs, :].norm(dim=-1).sum(-1)
    quats = inverse_kinematics(positions, skeleton, smooth_forward=False)  # (..., T, J, 4)
    root = positions[..., 0, :] * scale[..., None, None]  # (..., T, 3)
    return forward_kinematics(quats, root, tgt[..., None, :, :], skeleton)
