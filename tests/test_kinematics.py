"""Forward / inverse kinematics and retargeting on both skeletons."""

import math

import numpy as np
import pytest
import torch

from mlct.motion.kinematics import (
    bone_lengths, forward_kinematics, forward_kinematics_cont6d, inverse_kinematics,
    offsets_from_joints, uniform_skeleton,
)
from mlct.motion.quaternion import qnormalize, quat_from_axis_angle, quat_to_cont6d
from mlct.motion.skeleton import HUMANML3D, KIT
from motion_builders import random_motion, yaw

F64 = torch.float64
SKELETONS = [HUMANML3D, KIT]


def rest_positions(skeleton, offsets: np.ndarray) -> np.ndarray:
    """Closed form of FK at identity rotations: each joint is the sum of offsets down to it."""
    pos = np.zeros((skeleton.n_joints, 3))
    for j in range(1, skeleton.n_joints):
        pos[j] = pos[skeleton.parents[j]] + offsets[j]
    return pos


def random_local(skeleton, shape, seed=0):
    g = torch.Generator().manual_seed(seed)
    return qnormalize(torch.randn(*shape, skeleton.n_joints, 4, generator=g, dtype=F64))


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_fk_identity_and_root_rotation_closed_form(skeleton):
    identity = torch.zeros(skeleton.n_joints, 4, dtype=F64)
    identity[:, 0] = 1
    root = torch.tensor([0.5, 1.0, -2.0], dtype=F64)
    expected = rest_positions(skeleton, skeleton.target_offsets) + root.numpy()
    out = forward_kinematics(identity, root, skeleton.target_offsets, skeleton)
    np.testing.assert_allclose(out.numpy(), expected, atol=1e-9)
    # A root yaw of 90 degrees turns the whole body about the root: (x, z) -> (z, -x).
    turned = identity.clone()
    turned[0] = yaw(math.pi / 2)
    out = forward_kinematics(turned, root, skeleton.target_offsets, skeleton) - root
    rel = expected - root.numpy()
    expected = np.stack([rel[:, 2], rel[:, 1], -rel[:, 0]], -1)
    np.testing.assert_allclose(out.numpy(), expected, atol=1e-9)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_fk_keeps_bone_lengths_and_cont6d_agrees(skeleton):
    local = random_local(skeleton, (3, 10))  # batch 3, 10 frames
    root = torch.randn(3, 10, 3, dtype=F64)
    joints = forward_kinematics(local, root, skeleton.target_offsets, skeleton)
    assert joints.shape == (3, 10, skeleton.n_joints, 3)
    np.testing.assert_allclose(bone_lengths(joints, skeleton).numpy(),
                               np.broadcast_to(skeleton.bone_lengths, (3, 10, skeleton.n_joints)),
                               rtol=1e-12, atol=1e-9)
    via6d = forward_kinematics_cont6d(quat_to_cont6d(local), root, skeleton.target_offsets,
                                      skeleton)
    torch.testing.assert_close(via6d, joints)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
@pytest.mark.parametrize("smooth", [False, True])
def test_fk_of_ik_reproduces_positions(skeleton, smooth):
    local = random_local(skeleton, (2, 30), seed=1)
    root = torch.randn(2, 30, 3, dtype=F64)
    joints = forward_kinematics(local, root, skeleton.target_offsets, skeleton)  # (2, 30, J, 3)
    quats = inverse_kinematics(joints, skeleton, smooth_forward=smooth)
    # The reference forces frame 0's root to the identity.
    torch.testing.assert_close(quats[..., 0, 0, :],
                               torch.tensor([1.0, 0, 0, 0], dtype=F64).expand(2, 4))
    torch.testing.assert_close(quats.norm(dim=-1), torch.ones(quats.shape[:-1], dtype=F64))
    again = forward_kinematics(quats, joints[..., 0, :], skeleton.target_offsets, skeleton)
    scale = np.abs(skeleton.bone_lengths).max()
    torch.testing.assert_close(again, joints, atol=1e-9 * scale, rtol=0)


def test_ik_recovers_known_local_rotation():
    """Bending the left knee of the IK rest pose by 40 degrees about x: IK gives that rotation."""
    skeleton = HUMANML3D
    local = torch.zeros(skeleton.n_joints, 4, dtype=F64)
    local[:, 0] = 1
    knee = skeleton.index("left_knee")
    ankle = skeleton.index("left_ankle")
    bend = quat_from_axis_angle(torch.tensor([1.0, 0, 0], dtype=F64), math.radians(40))
    local[ankle] = bend  # the rotation stored at the ankle turns the bone knee -> ankle
    joints = forward_kinematics(local, torch.zeros(3, dtype=F64), skeleton.target_offsets, skeleton)
    quats = inverse_kinematics(joints[None], skeleton)[0]
    torch.testing.assert_close(quats[ankle], bend)
    torch.testing.assert_close(quats[knee], local[knee])


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_offsets_from_joints_are_raw_direction_times_length(skeleton):
    joints = forward_kinematics(random_local(skeleton, (), seed=2), torch.zeros(3, dtype=F64),
                                skeleton.target_offsets * 1.7, skeleton)
    np.testing.assert_allclose(offsets_from_joints(joints, skeleton).numpy(),
                               skeleton.target_offsets * 1.7, atol=1e-9)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_uniform_skeleton_retargets_lengths_and_scales_root(skeleton):
    unit = 1.0 if skeleton.unit == "m" else 1000.0
    big = torch.from_numpy(random_motion(skeleton, 40, 3, speed=unit, scale=1.25))
    out = uniform_skeleton(big, skeleton)
    np.testing.assert_allclose(bone_lengths(out, skeleton).numpy(),
                               np.broadcast_to(skeleton.bone_lengths, (40, skeleton.n_joints)),
                               atol=1e-9 * unit)
    torch.testing.assert_close(out[:, 0], big[:, 0] / 1.25)  # leg-length ratio 1 / 1.25
    # Bone directions are kept.
    parents = list(skeleton.parents[1:])
    d_in = big[:, 1:] - big[:, parents]
    d_out = out[:, 1:] - out[:, parents]
    torch.testing.assert_close(d_out / d_out.norm(dim=-1, keepdim=True),
                               d_in / d_in.norm(dim=-1, keepdim=True))
    # A subject that already has the target lengths is unchanged.
    same = torch.from_numpy(random_motion(skeleton, 20, 4, speed=unit))
    torch.testing.assert_close(uniform_skeleton(same, skeleton), same, atol=1e-9 * unit, rtol=0)
    # An explicit target subject (first frame) replaces the bundled bone lengths.
    target = big[7].numpy()
    out = uniform_skeleton(same, skeleton, target_joints=target)
    np.testing.assert_allclose(bone_lengths(out, skeleton).numpy()[5], skeleton.bone_lengths * 1.25,
                               atol=1e-9 * unit)


def test_fk_is_differentiable():
    skeleton = KIT
    local = random_local(skeleton, (4,), seed=5).requires_grad_(True)
    offsets = torch.from_numpy(skeleton.target_offsets).requires_grad_(True)
    root = torch.zeros(4, 3, dtype=F64, requires_grad=True)
    forward_kinematics(local, root, offsets, skeleton).square().sum().backward()
    for t in (local, offsets, root):
        assert t.grad is not None and torch.isfinite(t.grad).all()
    out = forward_kinematics(local.detach().float(), root.detach().float(),
                             skeleton.target_offsets, skeleton)
    assert out.dtype == torch.float32
