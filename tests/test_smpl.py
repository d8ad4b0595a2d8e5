"""SMPL/AMASS .npz export read back with numpy: the AMASS keys, and the joints that forward
kinematics of its poses gives are the fitted skeleton's (in AMASS's z-up world)."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.data.synth.build import make_motion
from mlct.errors import MlctError
from mlct.motion.skeleton import HUMANML3D, KIT
from mlct.motion.smpl import TO_AMASS, fit_for_smpl, smpl_joints, write_smpl_npz


def test_npz_round_trips_with_amass_keys(tmp_path):
    joints = make_motion(4, seed=0, skeleton=HUMANML3D).joints
    path = tmp_path / "m.npz"
    write_smpl_npz(path, joints, HUMANML3D, 20.0)
    data = np.load(path)
    n_frames = len(joints)
    assert data["poses"].shape == (n_frames, 156) and data["trans"].shape == (n_frames, 3)
    assert np.all(data["poses"][:, 66:] == 0) and np.all(data["betas"] == 0)
    assert str(data["gender"]) == "neutral" and float(data["mocap_framerate"]) == 20.0
    assert np.array_equal(data["root_orient"], data["poses"][:, :3])
    assert np.array_equal(data["pose_body"], data["poses"][:, 3:66])
    # plain SMPL's 24 x 3: the body's 22 joints as in `poses`, then two zero hand joints
    assert data["smpl_poses"].shape == (n_frames, 72)
    assert np.array_equal(data["smpl_poses"][:, :66], data["poses"][:, :66])
    assert np.all(data["smpl_poses"][:, 66:] == 0)
    fit = fit_for_smpl(joints, HUMANML3D, 20.0)
    rebuilt = smpl_joints(data)
    expected = fit.positions @ TO_AMASS.T
    assert np.linalg.norm(rebuilt - expected, axis=-1).max() < 1e-6
    lengths = np.linalg.norm(rebuilt[:, 1:] - rebuilt[:, list(HUMANML3D.parents[1:])], axis=-1)
    assert np.abs(lengths - lengths[0]).max() < 1e-6
    # AMASS is z up: the head is above the pelvis along z; HumanML3D's processing turns
    # (x, y, z) into (-x, z, y), which gives the fitted joints back.
    assert (rebuilt[:, 15, 2] > rebuilt[:, 0, 2]).all()
    back = np.stack([-rebuilt[..., 0], rebuilt[..., 2], rebuilt[..., 1]], -1)
    assert np.abs(back - fit.positions).max() < 1e-6


def test_zero_pose_is_the_t_pose():
    """A motion standing in SMPL's T-pose rest has (near) zero body poses."""
    fit = fit_for_smpl(make_motion(0, seed=0, skeleton=HUMANML3D).joints, HUMANML3D, 20.0)
    rest = np.zeros((1, 22, 3))
    for joint in fit.order[1:]:
        rest[0, joint] = rest[0, HUMANML3D.parents[joint]] + fit.offsets[joint]
    from mlct.motion.smpl import smpl_params

    params = smpl_params(np.repeat(rest + [0, 1, 0], 5, 0), HUMANML3D, 20.0)
    assert np.abs(params["pose_body"]).max() < 1e-6


def test_smpl_needs_the_humanml3d_skeleton(tmp_path):
    with pytest.raises(MlctError, match="humanml3d"):
        write_smpl_npz(tmp_path / "k.npz", make_motion(0, seed=0, skeleton=KIT).joints, KIT, 12.5)
    assert not (tmp_path / "k.npz").exists()
