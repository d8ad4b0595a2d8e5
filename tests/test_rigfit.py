"""The shared rotation fit (motion/rigfit.py): FK of the fit gives its positions, bones keep
their length, planted feet stay planted, twist does not snap."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mlct.data.synth.build import make_motion
from mlct.errors import MlctError
from mlct.motion.physics import foot_skating_ratio
from mlct.motion.rigfit import TWIST_RELAX_SECONDS, column_median, fit_rig, forward, swing
from mlct.motion.skeleton import HUMANML3D, KIT, Skeleton
from test_bvh import rigid_motion

SKELETONS = [HUMANML3D, KIT]


def bone_lengths(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    parents = [max(p, 0) for p in skeleton.parents]
    return np.linalg.norm(positions - positions[:, parents], axis=-1)  # (T, J)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("frames", [1, 2, 7, 196, 197])
def test_column_median_is_numpys_to_the_bit(frames, dtype):
    x = (np.random.default_rng(frames).standard_normal((frames, 22)) * 3).astype(dtype)
    if frames > 2:
        x[1, 5], x[0, 6] = np.nan, np.inf
    expected = np.median(x, axis=0)
    got = column_median(x)
    assert got.dtype == expected.dtype and np.array_equal(got, expected, equal_nan=True)


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_rigid_motion_is_fitted_exactly(skeleton):
    joints = rigid_motion(skeleton, 60, seed=1)
    fit = fit_rig(joints, skeleton)
    assert np.abs(fit.positions - joints).max() < 1e-9


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_fk_of_the_fit_gives_its_positions_with_constant_bones(skeleton):
    unit = 1000.0 if skeleton.unit == "mm" else 1.0
    for index in range(3):
        joints = make_motion(index, seed=0, skeleton=skeleton).joints
        fit = fit_rig(joints, skeleton)
        positions, world = forward(fit.parents, fit.order, fit.offsets, fit.root, fit.local)
        assert np.linalg.norm(positions - fit.positions, axis=-1).max() < 1e-9 * unit
        assert np.abs(fit.root - joints[:, 0]).max() < 1e-12 * unit  # the root trajectory
        lengths = bone_lengths(fit.positions, skeleton)
        assert np.abs(lengths - fit.lengths).max() < 1e-6 * unit
        # The generated-looking input stretches its bones; the fit does not, and stays close.
        assert np.linalg.norm(fit.positions - joints, axis=-1).max() < 0.03 * unit
        rotations = world.reshape(-1, 3, 3)  # orthonormal, no reflection
        assert np.abs(rotations @ np.swapaxes(rotations, -1, -2) - np.eye(3)).max() < 1e-9
        assert np.abs(np.linalg.det(rotations) - 1.0).max() < 1e-9


def test_given_lengths_are_used():
    joints = make_motion(0, seed=0, skeleton=HUMANML3D).joints
    fit = fit_rig(joints, HUMANML3D, lengths=HUMANML3D.bone_lengths)
    assert np.abs(bone_lengths(fit.positions, HUMANML3D) - HUMANML3D.bone_lengths).max() < 1e-9


@pytest.mark.parametrize("skeleton", SKELETONS, ids=lambda s: s.name)
def test_ankles_land_on_the_input_so_planted_feet_stay_planted(skeleton):
    unit = 1000.0 if skeleton.unit == "mm" else 1.0
    ankles = [skeleton.foot_left[0], skeleton.foot_right[0]]
    for index in range(4):
        joints = make_motion(index, seed=3, skeleton=skeleton).joints.astype(np.float64)
        fit = fit_rig(joints, skeleton)
        error = np.linalg.norm(fit.positions[:, ankles] - joints[:, ankles], axis=-1)
        assert (error < 1e-6 * unit).mean() > 0.8  # exactly, wherever the leg is not straight
        assert error.max() < 0.005 * unit
        # Horizontal ankle speed (per frame): the fit adds under 0.5 mm of sliding anywhere.
        slide = [np.linalg.norm(np.diff(p[:, ankles][..., [0, 2]], axis=0), axis=-1)
                 for p in (joints, fit.positions)]
        assert (slide[1] - slide[0]).max() < 0.0005 * unit
        toes = (skeleton.foot_left[1], skeleton.foot_right[1])
        skating = [foot_skating_ratio(p, skeleton, foot_joints=toes)
                   for p in (joints, fit.positions)]
        assert skating[1] <= skating[0] + 1e-9  # no new skating


def _arm_past_overhead(n_frames: int = 60) -> tuple[np.ndarray, float]:
    """A rigid standing body whose straight left arm sweeps up past the direction opposite its
    rest (hanging) one, 1 degree to the side of it: where the shortest turn from rest spins
    the arm by about 180 degrees within a frame or two. Returns the joints and the largest turn
    of the arm's direction between two frames (radians)."""
    pose = HUMANML3D.rest_offsets
    down = HUMANML3D.rest_directions[18]
    side = np.cross(down, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    front = np.cross(down, side)
    sweep = np.linspace(-1.0, 1.0, n_frames)[:, None]
    arm = -down + sweep * side + math.tan(math.radians(1.0)) * front
    arm /= np.linalg.norm(arm, axis=-1, keepdims=True)  # (T, 3)
    positions = np.empty((n_frames, HUMANML3D.n_joints, 3))
    positions[:, 0] = [0.0, 0.95, 0.0]
    for joint in range(1, HUMANML3D.n_joints):
        parent = HUMANML3D.parents[joint]
        offset = pose[joint]
        if joint in (18, 20):  # the left elbow and wrist, along the arm
            offset = arm * np.linalg.norm(pose[joint])
        positions[:, joint] = positions[:, parent] + offset
    turn = np.arccos(np.clip(np.sum(arm[1:] * arm[:-1], axis=-1), -1.0, 1.0)).max()
    return positions, float(turn)


def _largest_step_degrees(rotations: np.ndarray) -> float:
    step = Rotation.from_matrix(np.swapaxes(rotations[:-1], -1, -2) @ rotations[1:])
    return float(np.degrees(step.magnitude().max()))


def test_twist_stays_smooth_when_an_arm_passes_overhead():
    joints, arm_turn = _arm_past_overhead()
    fit = fit_rig(joints, HUMANML3D)
    assert np.abs(fit.positions - joints).max() < 1e-9
    # The upper arm's rotation (joint 16 turns the bone 16 -> 18): the shortest turn from rest
    # snaps by tens of degrees in one frame there; the fit turns a frame by about the arm's
    # own turn plus the unwinding of the flip's twist (180 degrees over TWIST_RELAX_SECONDS).
    lengths = np.linalg.norm(fit.offsets[18])
    rest = fit.offsets[18] / lengths
    target = (joints[:, 18] - joints[:, 16]) / lengths
    plain = _largest_step_degrees(swing(np.broadcast_to(rest, target.shape).copy(), target))
    unwind = 180.0 / (TWIST_RELAX_SECONDS * HUMANML3D.fps)
    smooth = _largest_step_degrees(fit.local[:, 16])
    assert plain > 60.0
    assert smooth < np.degrees(arm_turn) + 2 * unwind and smooth < plain / 4


@pytest.mark.parametrize("bad, message", [
    (np.zeros((10, 21, 3)), "shape"), (np.zeros((0, 22, 3)), "shape"),
    (np.full((5, 22, 3), np.nan), "NaN"),
])
def test_bad_joints_are_one_line_errors(bad, message):
    with pytest.raises(MlctError, match=message):
        fit_rig(bad, HUMANML3D)


def test_a_planted_toe_stays_planted_while_the_heel_lifts_and_the_foot_stretches():
    """Push-off on a generated-like foot: the toe stays put, the heel rises and the foot bone
    grows by 1 cm. A fixed-length foot cannot keep both ends; the fit keeps the still one."""
    n_frames = 40
    rest = np.zeros((HUMANML3D.n_joints, 3))
    for joint in range(1, HUMANML3D.n_joints):
        rest[joint] = rest[HUMANML3D.parents[joint]] + HUMANML3D.rest_offsets[joint]
    ankle, toe = HUMANML3D.foot_left
    knee = HUMANML3D.parents[ankle]
    hip = HUMANML3D.parents[knee]

    def turn_x(angle: float) -> np.ndarray:
        c, s = math.cos(angle), math.sin(angle)
        return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])

    # a bent left knee (thigh forward, shin back), the foot flat as in the rest pose
    thigh, shin = turn_x(-0.35), turn_x(-0.35) @ turn_x(0.7)
    foot_offset = rest[toe] - rest[ankle]
    rest[knee] = rest[hip] + thigh @ (rest[knee] - rest[hip])
    rest[ankle] = rest[knee] + shin @ HUMANML3D.rest_offsets[ankle]
    rest[toe] = rest[ankle] + foot_offset
    rest[:, 1] -= rest[:, 1].min()
    joints = np.repeat(rest[None], n_frames, 0)
    foot = rest[toe] - rest[ankle]
    length = np.linalg.norm(foot)
    lift = np.linspace(0.0, 0.5, n_frames)  # radians, the heel rising about the toe
    grow = np.linspace(0.0, 0.01, n_frames)  # metres of stretch
    back = -foot / length
    for t in range(n_frames):
        turned = back * np.cos(lift[t]) + np.array([0.0, 1.0, 0.0]) * np.sin(lift[t])
        joints[t, ankle] = rest[toe] + (length + grow[t]) * turned / np.linalg.norm(turned)
    fit = fit_rig(joints, HUMANML3D)
    toe_path = fit.positions[:, toe]
    assert np.linalg.norm(toe_path - rest[toe], axis=-1).max() < 1e-3  # planted, to 1 mm
    ankle_error = np.linalg.norm(fit.positions[:, ankle] - joints[:, ankle], axis=-1)
    assert ankle_error.max() > 0.004  # the moving heel takes the stretch instead


@pytest.mark.parametrize("size", [1, 2, 3, 4, 7, 12])
def test_moving_average_is_scipys_nearest_uniform_filter(size):
    from scipy.ndimage import uniform_filter1d

    from mlct.motion.rigfit import moving_average

    x = np.random.default_rng(size).normal(size=40)
    np.testing.assert_allclose(moving_average(x, size), uniform_filter1d(x, size, mode="nearest"),
                               atol=1e-12)
    np.testing.assert_allclose(moving_average(x[:3], size),
                               uniform_filter1d(x[:3], size, mode="nearest"), atol=1e-12)


def test_turns_about_an_axis_are_scipys_rotation_vectors():
    from mlct.motion.rigfit import _axis_rotation

    axis = np.array([0.3, -0.8, 0.52]) / np.linalg.norm([0.3, -0.8, 0.52])
    angles = np.linspace(-7.0, 7.0, 57)
    np.testing.assert_allclose(_axis_rotation(axis, angles),
                               Rotation.from_rotvec(angles[:, None] * axis).as_matrix(), atol=1e-12)
