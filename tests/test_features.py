"""The standard motion representation: joints -> features -> joints, and golden cases.

Agreement with the reference processing, measured during development (not re-run here: the tests
need neither the reference code nor its data). Reference = process_file + recover_from_ric of
EricGuo5513/text-to-motion scripts/motion_process.py with its common/quaternion.py and
common/skeleton.py (float32 inside), target offsets = our bundled bone lengths, same raw input.
Max abs difference of our float64 output vs the reference:

| input                                            | features  | joints   | recovered |
|--------------------------------------------------|-----------|----------|-----------|
| HumanML3D random FK motion, turns through 180deg | 1.1e-5 *  | 1.1e-6   | 1.9e-1 ** |
| HumanML3D random FK motion, x1.15 subject        | 6.4e-6    | 1.2e-6   | 1.2e-6    |
| HumanML3D random FK motion, larger rotations     | 1.0e-4 *  | 2.0e-6   | 2.1e-1 ** |
| HumanML3D walk straight / standing still         | 7.1e-6    | 6.5e-7   | 6.5e-7    |
| HumanML3D turn in place (crosses 180 deg)        | 4.3e-6 *  | 1.0e-6   | 1.9e-2 ** |
| HumanML3D 012314 new_joints, turned/scaled/moved | 1.8e-5    | 1.9e-6   | 1.9e-6    |
| HumanML3D 012314 new_joints as is                | 6.6e-6    | 1.7e-6   | 1.7e-6    |
| KIT random FK motion, 180 deg turn (mm)          | 2.1e-3 *  | 1.6e-3   | 365 **    |
| KIT random FK motion, x1.15 subject (mm)         | 1.2e-3    | 1.1e-3   | 1.1e-3    |
| KIT random FK motion, larger rotations (mm)      | 2.3e-3 *  | 3.3e-3   | 368 **    |

All features agree to float32 precision (relative ~1e-6; largest in the 6D rotations of bones
nearly opposite to their raw offset, where the reference's float32 qbetween is ill-conditioned),
root angular velocity to <= 4e-6. * except one frame per 180 degree heading crossing, where the
reference's root angular velocity has the wrong sign (ours -0.025139, reference +0.025137): our
one deliberate deviation (w >= 0 before arcsin). ** the reference's own round trip is off by that
much after the crossing (its recovered heading is wrong from there on); ours is exact (< 1e-11).
Rigid KIT rest-pose motions are not comparable: KIT's raw offsets point the hips and shoulders
opposite to a body facing +Z, and the reference's qbetween returns NaN for opposite vectors.
recover_from_ric on the distributed new_joint_vecs/012314.npy vs new_joints/012314.npy:
0.0 in float32, 2.1e-7 in float64.
"""

import math

import numpy as np
import pytest
import torch

from mlct.errors import MlctError
from mlct.motion.features import (
    MotionFeatures, features_to_joints, foot_contacts, joints_to_features, n_joints_for_dim,
    recover_from_ric, recover_root_rot_pos, split_features,
)
from mlct.motion.skeleton import HUMANML3D, KIT
from motion_builders import random_motion, rigid_motion, square_pose_offsets

SKELETONS = [HUMANML3D, KIT]
F64 = np.float64


def unit(skeleton) -> float:
    """Skeleton units per metre (KIT is in millimetres)."""
    return 1.0 if skeleton.unit == "m" else 1000.0


def rest_root_height(skeleton) -> float:
    """Root height above the lowest joint of the goldens' pose, from the skeleton constants."""
    offsets = square_pose_offsets(skeleton)
    y = np.zeros(skeleton.n_joints)
    for j in range(1, skeleton.n_joints):
        y[j] = y[skeleton.parents[j]] + offsets[j, 1]
    return -y.min()


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_shapes_dtype_and_normalization(skeleton):
    joints = random_motion(skeleton, 60, 0, speed=unit(skeleton))
    out = joints_to_features(joints, skeleton)
    assert isinstance(out, MotionFeatures)
    assert out.features.shape == (59, skeleton.feature_dim) and out.features.dtype == np.float32
    assert out.joints.shape == (60, skeleton.n_joints, 3) and out.joints.dtype == np.float32
    assert skeleton.feature_dim == {"humanml3d": 263, "kit": 251}[skeleton.name]
    assert n_joints_for_dim(skeleton.feature_dim) == skeleton.n_joints
    j = out.joints.astype(F64)
    tol = 1e-5 * unit(skeleton)
    assert abs(j[..., 1].min()) < tol  # on the floor
    np.testing.assert_allclose(j[0, 0, [0, 2]], 0, atol=tol)  # first root at the xz origin
    r_hip, l_hip, r_sh, l_sh = skeleton.face_joints
    across = j[0, r_hip] - j[0, l_hip] + j[0, r_sh] - j[0, l_sh]
    assert abs(across[2]) < tol and across[0] < 0  # right side on -x: facing +Z
    groups = split_features(out.features, skeleton.layout)
    assert set(np.unique(groups["foot_contact"])) <= {0.0, 1.0}


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
@pytest.mark.parametrize("seed,heading", [(0, (0.3, 0.3 + 1.5 * math.pi)), (1, (2.0, -2.5)),
                                          (2, (-1.0, 1.0))])
def test_round_trip_reproduces_normalized_joints(skeleton, seed, heading):
    """joints -> features -> recover_from_ric == normalized joints (frames 0..T-2).

    Measured: < 1e-14 m (HumanML3D) and < 1.5e-11 mm (KIT) in float64; with float32 features
    5e-7 m and 6e-4 mm (float32 rounding of the stored features, relative 1e-7).
    Two of the three motions turn through a heading of 180 degrees.
    """
    joints = random_motion(skeleton, 150, seed, heading=heading, speed=1.3 * unit(skeleton),
                           scale=1.1)
    out = joints_to_features(joints, skeleton, dtype=np.float64)
    rec = features_to_joints(out.features)
    assert rec.shape == (149, skeleton.n_joints, 3)
    assert np.abs(rec - out.joints[:-1]).max() <= 1e-4  # native units, float64 features
    out32 = joints_to_features(joints, skeleton)
    rec32 = recover_from_ric(torch.from_numpy(out32.features)).numpy()
    assert np.abs(rec32 - out32.joints[:-1]).max() <= 1e-4 * unit(skeleton)  # 0.1 mm, float32


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_golden_standing_still(skeleton):
    joints = rigid_motion(skeleton, 40, heading0=2.0, scale=1.2)
    g = split_features(joints_to_features(joints, skeleton, dtype=F64).features, skeleton.layout)
    for name in ("root_rot_velocity", "root_linear_velocity", "local_velocity"):
        np.testing.assert_allclose(g[name], 0, atol=1e-9 * unit(skeleton))
    # Retargeted to the target lengths: the root stands at the rest pose's height.
    np.testing.assert_allclose(g["root_height"], rest_root_height(skeleton), rtol=1e-9)
    np.testing.assert_array_equal(g["foot_contact"], 1.0)
    for name in ("ric", "rotations"):
        np.testing.assert_allclose(g[name], np.broadcast_to(g[name][0], g[name].shape), atol=1e-9)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
@pytest.mark.parametrize("scale", [1.0, 1.25])
def test_golden_walking_straight(skeleton, scale):
    """A rigid body gliding along its heading at `speed` (any initial heading): after facing
    normalization the root moves along +Z at speed / fps per frame (divided by the subject's
    scale, which the uniform skeleton undoes); no turning; every joint has the root's velocity."""
    speed, heading = 1.4 * unit(skeleton) * scale, 0.6
    velocity = (speed * math.sin(heading), speed * math.cos(heading))
    joints = rigid_motion(skeleton, 60, heading0=heading, velocity=velocity, scale=scale)
    g = split_features(joints_to_features(joints, skeleton, dtype=F64).features, skeleton.layout)
    step = speed / scale / skeleton.fps
    atol = 1e-9 * unit(skeleton)
    np.testing.assert_allclose(g["root_rot_velocity"], 0, atol=1e-12)
    np.testing.assert_allclose(g["root_linear_velocity"][:, 0], 0, atol=atol)
    np.testing.assert_allclose(g["root_linear_velocity"][:, 1], step, rtol=1e-9)
    np.testing.assert_allclose(g["root_height"], rest_root_height(skeleton), rtol=1e-9)
    vel = g["local_velocity"].reshape(59, skeleton.n_joints, 3)
    np.testing.assert_allclose(vel, np.broadcast_to([0.0, 0.0, step], vel.shape), atol=atol)
    # Feet move step per frame, far above the contact threshold.
    np.testing.assert_array_equal(g["foot_contact"], 0.0)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_golden_turning_in_place(skeleton):
    """Turning about the root at d = 0.031 rad per frame (heading crosses 180 deg at frame ~101):
    the root angular velocity is -d/2 (half-angle; negative for a turn from +Z towards +X) at
    every frame the facing smoother's 'nearest' boundary cannot reach (sigma 20, truncated at 80
    frames: 80 <= t <= T - 82), including the crossing where the reference has the sign wrong."""
    d, n = 0.031, 200
    joints = rigid_motion(skeleton, n, heading0=-0.4, turn_rate=d * skeleton.fps)
    feats = joints_to_features(joints, skeleton, dtype=F64).features
    g = split_features(feats, skeleton.layout)
    interior = slice(80, n - 81)
    np.testing.assert_allclose(g["root_rot_velocity"][interior, 0], -d / 2, rtol=1e-9)
    np.testing.assert_allclose(g["root_linear_velocity"], 0, atol=1e-9 * unit(skeleton))
    np.testing.assert_allclose(g["root_height"], rest_root_height(skeleton), rtol=1e-9)
    ric = g["ric"][interior]  # the body does not change in its own frame
    np.testing.assert_allclose(ric, np.broadcast_to(ric[0], ric.shape), atol=1e-9 * unit(skeleton))
    # The recovered heading turns by d per frame all the way through 180 degrees.
    r_rot, _ = recover_root_rot_pos(torch.from_numpy(feats))
    half = torch.atan2(r_rot[..., 2], r_rot[..., 0]).numpy()
    np.testing.assert_allclose(np.diff(half[interior]), -d / 2, rtol=1e-9)


def test_foot_contacts_threshold():
    skeleton = HUMANML3D
    joints = torch.zeros(4, skeleton.n_joints, 3, dtype=torch.float64)
    ankle = skeleton.foot_left[0]
    toe = skeleton.foot_right[1]
    joints[1:, ankle, 0] = 0.04  # moves 0.04: 0.0016 < 0.002, in contact
    joints[2:, toe, 2] = 0.05  # moves 0.05 at frame 1: 0.0025 >= 0.002, not in contact
    expected = np.ones((3, 4))
    expected[1, 3] = 0.0
    np.testing.assert_array_equal(foot_contacts(joints, skeleton).numpy(), expected)


def test_recover_from_ric_is_differentiable_batched_and_keeps_dtype():
    n_joints, n_frames = 4, 5
    dim = 12 * n_joints - 1
    g = torch.Generator().manual_seed(0)
    x = (0.3 * torch.randn(1, n_frames, dim, generator=g, dtype=torch.float64)).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda f: recover_from_ric(f, n_joints), (x,))
    out = recover_from_ric(x.detach().float())
    assert out.dtype == torch.float32 and out.shape == (1, n_frames, n_joints, 3)
    # Leading dims: a (2, 3, T, D) batch equals its items one by one.
    skeleton = HUMANML3D
    feats = np.stack([joints_to_features(random_motion(skeleton, 30, s), skeleton).features
                      for s in range(6)]).reshape(2, 3, 29, skeleton.feature_dim)
    batch = torch.from_numpy(feats).requires_grad_(True)
    out = recover_from_ric(batch, skeleton.n_joints)
    assert out.shape == (2, 3, 29, 22, 3)
    torch.testing.assert_close(out[1, 2], recover_from_ric(torch.from_numpy(feats[1, 2])))
    out.square().mean().backward()
    assert torch.isfinite(batch.grad).all() and batch.grad.abs().sum() > 0
    np.testing.assert_allclose(features_to_joints(feats)[0, 1], out[0, 1].detach().numpy(),
                               atol=1e-5)


def test_bad_input_is_one_clear_error():
    with pytest.raises(MlctError, match="shape"):
        joints_to_features(np.zeros((10, 21, 3)), HUMANML3D)
    with pytest.raises(MlctError, match="2 frames"):
        joints_to_features(np.zeros((1, 22, 3)), HUMANML3D)
    bad = random_motion(HUMANML3D, 10, 0)
    bad[3, 4, 1] = np.nan
    with pytest.raises(MlctError, match="NaN"):
        joints_to_features(bad, HUMANML3D)
    with pytest.raises(MlctError, match="degenerate"):
        joints_to_features(np.zeros((5, 22, 3)), HUMANML3D)
    with pytest.raises(MlctError, match="feature width"):
        recover_from_ric(torch.zeros(5, 100))


def test_recover_a_single_frame() -> None:
    """A one-frame motion (mlct generate --seconds 0.001) recovers to one pose, not an error."""
    import torch

    from mlct.motion.features import recover_from_ric

    features = torch.zeros(1, 263)
    features[0, 3] = 0.9  # root height
    joints = recover_from_ric(features)
    assert joints.shape == (1, 22, 3) and float(joints[0, 0, 1]) == pytest.approx(0.9)
    assert recover_from_ric(torch.zeros(2, 1, 263)).shape == (2, 1, 22, 3)
