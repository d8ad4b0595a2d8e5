"""The Unitree G1 retarget (motion/robots/): its qpos replayed through forward kinematics puts the
feet and hands where the retarget aimed them and near the generated joints, every angle within
the MJCF's limits, a planted foot stays put on the floor, the CSV and .npz read back, and a bad
input is a one-line error."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mlct.cli import main
from mlct.data.synth.actions import Action, Script
from mlct.data.synth.compose import compose
from mlct.data.synth.motions import Style
from mlct.data.synth.rig import make_rig
from mlct.errors import MlctError
from mlct.generate.output.exports import export_bytes, save_motion
from mlct.generate.output.generated import GeneratedMotion
from mlct.motion.features import joints_to_features, recover_from_ric
from mlct.motion.robots import g1
from mlct.motion.robots.chain import quat_to_matrix
from mlct.motion.robots.files import read_robot, write_robot
from mlct.motion.robots.retarget import CHAIN, _spans, forward, retarget_g1
from mlct.motion.skeleton import HUMANML3D, KIT

ACTIONS = {
    "walk": Action("walk", {"speed": "normal", "direction": "forward"}),
    "squat": Action("squat", {"count": 2}),
    "wave": Action("wave", {"hand": "right", "count": 3}),
    "kick": Action("kick", {"leg": "left", "count": 1}),
}
SIDES = ("left", "right")


def procedural(name: str) -> np.ndarray:
    rig = make_rig(HUMANML3D)
    style = Style(arm_length=rig.arm_length, shoulder_x=rig.shoulder_x)
    return compose(Script((ACTIONS[name],)), rig, style, np.random.default_rng(0),
                   HUMANML3D.fps).positions


@pytest.fixture(scope="module")
def motions() -> dict[str, np.ndarray]:
    out = {name: procedural(name) for name in ACTIONS}
    # as a model's output: a walk's features decoded back to joints (as the dataset's are)
    features = joints_to_features(out["walk"], HUMANML3D).features
    out["decoded"] = recover_from_ric(torch.from_numpy(features)).numpy()
    return out


@pytest.fixture(scope="module")
def retargets(motions, tmp_path_factory):
    folder = tmp_path_factory.mktemp("g1")
    # FK reads the written file, not the solver's arrays: the export is what is checked
    return {name: (retarget_g1(joints), read_robot(write_robot(folder / f"{name}.g1.npz",
                                                               retarget_g1(joints))))
            for name, joints in motions.items()}


def test_the_table_stands_the_g1_on_its_soles_at_the_mjcf_height():
    # the MJCF's pelvis height, 0.793 m, with every joint at zero: the contact spheres touch z = 0
    pose = CHAIN.forward(np.array([[0.0, 0.0, 0.793]]), np.eye(3)[None], np.zeros((1, 29)))
    for side in SIDES:
        body = CHAIN.body(f"{side}_ankle_roll_link")
        for corner in g1.SOLE_CORNERS:
            assert abs(pose.point(body, corner)[0, 2] - g1.SOLE_RADIUS) < 0.002
    assert len(CHAIN.joint_names) == 29 and CHAIN.joint_names[3] == "left_knee_joint"


@pytest.mark.parametrize("name", [*ACTIONS, "decoded"])
def test_fk_of_the_written_qpos_puts_feet_and_hands_on_their_targets(retargets, name):
    solved, written = retargets[name]
    pose = forward(written)
    for side in SIDES:
        foot = pose.pos[:, CHAIN.body(f"{side}_ankle_roll_link")]
        hand = pose.pos[:, CHAIN.body(f"{side}_wrist_yaw_link")]
        assert np.linalg.norm(foot - solved.targets[f"{side}_foot"], axis=-1).max() < 0.03
        assert np.linalg.norm(hand - solved.targets[f"{side}_hand"], axis=-1).max() < 0.03
        # and near the generated joints, scaled by the leg ratio: the feet within a held
        # contact's slide, the hands within what the G1's other arm proportions move them
        human = written.human
        ankle = human[:, HUMANML3D.joint_names.index(f"{side}_ankle")]
        wrist = human[:, HUMANML3D.joint_names.index(f"{side}_wrist")]
        assert np.linalg.norm((foot - ankle)[:, :2], axis=-1).max() < 0.06
        assert np.linalg.norm(hand - wrist, axis=-1).max() < 0.12


@pytest.mark.parametrize("name", [*ACTIONS, "decoded"])
def test_every_angle_is_within_its_limit(retargets, name):
    angles = retargets[name][1].qpos[:, 7:]
    assert angles.shape[1] == len(g1.JOINT_NAMES)
    assert (angles >= CHAIN.lower - 1e-9).all() and (angles <= CHAIN.upper + 1e-9).all()


@pytest.mark.parametrize("name", [*ACTIONS, "decoded"])
def test_a_planted_foot_stays_on_the_floor_where_it_stands(retargets, name):
    solved, written = retargets[name]
    pose = forward(written)
    assert written.contacts.any(axis=0).all()  # each foot stands at some point
    for s, side in enumerate(SIDES):
        body = CHAIN.body(f"{side}_ankle_roll_link")
        soles = np.stack([pose.point(body, np.subtract(c, (0, 0, g1.SOLE_RADIUS)))
                          for c in g1.SOLE_CORNERS], 1)  # (T, 4, 3)
        for start, end in _spans(written.contacts[:, s]):
            centre = soles[start:end].mean(axis=1)[:, :2]
            assert np.linalg.norm(centre - centre.mean(axis=0), axis=-1).max() < 0.015
            assert np.abs(soles[start:end, :, 2]).max() < 0.015  # flat, on the floor
    assert (soles[..., 2] > -0.015).all()  # and never through it


def test_axes_walking_forward_moves_the_g1_along_plus_x_facing_it(retargets):
    qpos = retargets["walk"][1].qpos
    travel = qpos[-1, :3] - qpos[0, :3]
    assert travel[0] > 1.0 and abs(travel[1]) < 0.2 * travel[0]
    assert 0.6 < qpos[:, 2].mean() < 0.8  # the pelvis at about the G1's standing height
    forward_axis = quat_to_matrix(qpos[:, 3:7])[:, :, 0]
    assert (forward_axis[:, 0] > 0.9).all()
    quat = qpos[:, 3:7]
    assert np.allclose(np.linalg.norm(quat, axis=-1), 1.0)
    assert (np.sum(quat[1:] * quat[:-1], axis=-1) > 0).all()  # no sign flips between frames


def test_csv_and_npz_round_trip(retargets, motions, tmp_path):
    solved = retargets["wave"][0]
    motion = GeneratedMotion("a person waves", np.zeros((len(motions["wave"]), 0)),
                             motions["wave"], 20.0, "humanml3d", 0)
    csv = save_motion(motion, tmp_path / "wave.G1.csv")  # the generate path; any case
    header, first = csv.read_text().splitlines()[:2]
    assert header.split(",") == ["time", "root_x", "root_y", "root_z", "root_qw", "root_qx",
                                 "root_qy", "root_qz", *g1.JOINT_NAMES]
    assert len(first.split(",")) == 8 + 29
    back = read_robot(csv)
    assert back.fps == 20.0 and back.joint_names == g1.JOINT_NAMES
    assert np.abs(back.qpos - solved.qpos).max() < 1e-6
    npz = tmp_path / "wave.g1.npz"
    npz.write_bytes(export_bytes(motion, ".g1.npz"))  # the server's download
    data = np.load(npz)
    assert data["qpos"].shape == (len(motions["wave"]), 36) and float(data["fps"]) == 20.0
    assert data["human_joints"].shape == (len(motions["wave"]), 22, 3)
    assert "unitree_mujoco" in str(data["source"]) and "BSD" in str(data["source"])
    assert np.array_equal(read_robot(npz).qpos, solved.qpos)


def test_bad_inputs_are_one_line_errors(motions, tmp_path, capsys):
    with pytest.raises(MlctError, match="HumanML3D's 22 joints"):
        retarget_g1(np.zeros((30, 21, 3)), KIT)
    with pytest.raises(MlctError, match=r"shape \(T, 22, 3\)"):
        retarget_g1(np.zeros((30, 20, 3)))
    with pytest.raises(MlctError, match="not an mlct-robot"):
        np.savez(tmp_path / "other.npz", a=1)
        read_robot(tmp_path / "other.npz")
    np.save(tmp_path / "kit.npy", np.zeros((30, 21, 3), np.float32))
    np.save(tmp_path / "walk.npy", motions["walk"].astype(np.float32))
    cases = [
        (["retarget", str(tmp_path / "kit.npy"), "--out", str(tmp_path / "k.g1.csv")],
         "HumanML3D's 22 joints"),
        (["retarget", str(tmp_path / "walk.npy"), "--out", str(tmp_path / "w.csv")],
         "retarget writes"),
        (["retarget", str(tmp_path / "walk.npy"), "--out", str(tmp_path / "w.g1.csv"),
          "--rig", "mixamo"], "--rig applies to"),
        # refused before the model loads: no model is needed to say so
        (["generate", "a person walks", "--out", str(tmp_path / "w.g1.npz"), "--rig", "unreal"],
         "--rig applies to"),
        (["generate", "a person walks", "--features", "--out", str(tmp_path / "w.g1.npz")],
         "--features writes .npy"),
    ]
    for argv, words in cases:
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kit.npy", "other.npz", "walk.npy"]


def test_retarget_command_writes_the_g1_csv(tmp_path, motions, capsys):
    np.save(tmp_path / "kick.npy", motions["kick"].astype(np.float32))
    out = tmp_path / "kick.g1.csv"
    assert main(["retarget", str(tmp_path / "kick.npy"), "--out", str(out)]) == 0
    assert read_robot(out).qpos.shape == (len(motions["kick"]), 36)
