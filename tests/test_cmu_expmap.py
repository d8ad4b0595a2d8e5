"""The CMU expmap set (motion/cmu_expmap.py, data/corpora/cmu_expmap.py): its forward kinematics
against closed forms, and a release folder of sequences made here (a stepping body in the set's
117 values a frame) imported as a clean dataset with the set's captions and CMU's license."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mlct.cli import main
from mlct.data.check import check_dataset
from mlct.data.corpora import import_corpus
from mlct.data.corpora.cmu_expmap import ACTIONS, CMU_EXPMAP
from mlct.data.corpora.wording import FORMS
from mlct.data.importer import _load_bvh
from mlct.errors import MlctError
from mlct.motion.cmu_expmap import (EXPMAP_FPS, JOINT_NAMES, SKELETON, forward_kinematics,
                                    read_expmap)
from mlct.motion.skeleton import HUMANML3D

pytestmark = pytest.mark.usefixtures("one_thread")

_J = {name: j for j, name in enumerate(JOINT_NAMES)}


def _rest(name: str) -> np.ndarray:
    """A joint's rest position: its offsets summed up the chain."""
    parent_of = {n: (p, o) for n, p, o in SKELETON}
    total = np.zeros(3)
    while name is not None:
        parent, offset = parent_of[name]
        total += offset
        name = parent
    return total


def _expmap(frames: int, step: float = 0.18, seed: int = 0) -> np.ndarray:
    """(frames, 117): a body stepping forward along +z at the set's 120 fps, legs swinging
    about x, arms lowered to the sides, a little noise on the spine."""
    rng = np.random.default_rng(seed)
    values = np.zeros((frames, 117))
    t = np.arange(frames) / EXPMAP_FPS
    values[:, 0:3] = np.stack([np.zeros(frames), 17.5 + 0.2 * np.sin(4 * np.pi * t),
                               step * np.arange(frames)], -1)

    def rot(joint: str, vector: np.ndarray) -> None:
        values[:, 3 + 3 * _J[joint]: 6 + 3 * _J[joint]] = vector

    swing = 0.4 * np.sin(2 * np.pi * t)[:, None]
    rot("lfemur", swing * [1, 0, 0])
    rot("rfemur", -swing * [1, 0, 0])
    rot("ltibia", np.abs(swing) * [-1, 0, 0])
    rot("rtibia", np.abs(swing) * [-1, 0, 0])
    rot("lhumerus", np.tile([0, 0, 1.2], (frames, 1)))  # row vectors: +z lowers the left arm
    rot("rhumerus", np.tile([0, 0, -1.2], (frames, 1)))
    rot("upperback", 0.02 * rng.standard_normal((frames, 3)))
    return values


def _write(path: Path, values: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(",".join(f"{v:.6g}" for v in row) for row in values) + "\n")


def test_zero_rotations_give_the_rest_pose_at_the_root():
    values = np.zeros((2, 117))
    values[1, :3] = [1.0, 17.0, -3.0]
    positions = forward_kinematics(values)
    assert positions.shape == (2, 38, 3)
    for name in ("lfemur", "head_end", "rwrist", "ltoes_end"):
        np.testing.assert_allclose(positions[0, _J[name]], _rest(name), atol=1e-12)
        np.testing.assert_allclose(positions[1, _J[name]], _rest(name) + [1.0, 17.0, -3.0],
                                   atol=1e-12)
    assert _rest("head_end")[1] > 0 > _rest("lfoot")[1]  # y is up
    assert _rest("lfemur")[0] > 0 > _rest("rfemur")[0]  # left is +x


def test_rotations_compose_in_row_vectors():
    """x_j = o_j R_p + x_p, R_j = E_j R_p: a quarter turn of the root about y takes the left
    hip from +x to +z (o R = R^T o), and a knee bend turns only the shin below it."""
    values = np.zeros((1, 117))
    values[0, 3:6] = [0.0, np.pi / 2, 0.0]
    positions = forward_kinematics(values)
    hip = _rest("lfemur") - _rest("lhipjoint")
    np.testing.assert_allclose(positions[0, _J["lfemur"]], [-hip[2], hip[1], hip[0]],
                               atol=1e-12)
    values = np.zeros((1, 117))
    values[0, 3 + 3 * _J["ltibia"]: 6 + 3 * _J["ltibia"]] = [np.pi / 2, 0.0, 0.0]
    positions = forward_kinematics(values)
    np.testing.assert_allclose(positions[0, _J["ltibia"]], _rest("ltibia"), atol=1e-12)
    shin = positions[0, _J["lfoot"]] - positions[0, _J["ltibia"]]
    x, y, z = _rest("lfoot") - _rest("ltibia")
    np.testing.assert_allclose(shin, [x, z, -y], atol=1e-12)  # o Rx(90 degrees)
    np.testing.assert_allclose(positions[0, _J["ltoes"]] - positions[0, _J["lfoot"]],
                               (_rest("ltoes") - _rest("lfoot")) @ np.array(
                                   [[1, 0, 0], [0, 0, -1], [0, 1, 0]]), atol=1e-12)


def test_a_file_reads_at_120_fps_and_a_bad_one_is_named(tmp_path):
    _write(tmp_path / "walking_1.txt", _expmap(5))
    clip = read_expmap(tmp_path / "walking_1.txt")
    assert clip.fps == 120.0 and clip.positions.shape == (5, 38, 3)
    assert clip.joint_names == JOINT_NAMES
    (tmp_path / "short.txt").write_text("1,2,3\n")
    with pytest.raises(MlctError, match=r"short.txt: 3 values a frame, expected 117"):
        read_expmap(tmp_path / "short.txt")
    (tmp_path / "words.txt").write_text("a,b\n")
    with pytest.raises(MlctError, match="words.txt: not comma-separated numbers"):
        read_expmap(tmp_path / "words.txt")


def test_the_set_maps_onto_the_skeleton_by_cmus_bone_names(tmp_path):
    _write(tmp_path / "walking_1.txt", _expmap(6))
    positions, fps = _load_bvh(tmp_path / "walking_1.txt", HUMANML3D, CMU_EXPMAP.joint_map,
                               CMU_EXPMAP.between, CMU_EXPMAP.read)
    raw = read_expmap(tmp_path / "walking_1.txt").positions
    names = HUMANML3D.joint_names
    assert fps == 120.0
    for ours, bone in (("pelvis", "root"), ("left_hip", "lfemur"), ("right_knee", "rtibia"),
                       ("left_foot", "ltoes"), ("neck", "upperneck"), ("head", "head"),
                       ("right_shoulder", "rhumerus"), ("left_wrist", "lwrist")):
        np.testing.assert_allclose(positions[:, names.index(ours)], raw[:, _J[bone]])
    halfway = (raw[:, _J["thorax"]] + raw[:, _J["upperneck"]]) / 2
    np.testing.assert_allclose(positions[:, names.index("spine3")], halfway)


@pytest.fixture(scope="module")
def release(tmp_path_factory):
    """The set's folders: train and test, an action per folder, extra walks apart."""
    root = tmp_path_factory.mktemp("cmu_expmap") / "cmu_mocap"
    _write(root / "train" / "walking" / "walking_1.txt", _expmap(300, seed=1))
    _write(root / "train" / "walking_extra" / "walking_13.txt", _expmap(320, seed=2))
    _write(root / "test" / "washwindow" / "washwindow_1.txt", _expmap(300, step=0.0, seed=3))
    (root / "train" / "walking" / "notes.txt").write_text("not a sequence\n")
    return root


def test_a_release_imports_as_a_clean_dataset_with_cmus_license(release, tmp_path):
    out = tmp_path / "expmap"
    summary = import_corpus("cmu-expmap", release, out, seed=0)
    assert summary.clips == 3 and summary.motions == 3
    assert check_dataset(out) == []
    records = {r["name"]: r for r in map(json.loads,
                                         (out / "provenance.jsonl").read_text().splitlines())}
    assert set(records) == {"cmu_expmap_train_walking_1", "cmu_expmap_train_walking_extra_13",
                            "cmu_expmap_test_washwindow_1"}
    wash = records["cmu_expmap_test_washwindow_1"]
    assert wash["corpus"] == "cmu-expmap" and wash["commercial_use"] is True
    assert wash["file"] == "test/washwindow/washwindow_1.txt"
    assert wash["labels"] == {"content": "washwindow", "set_split": "test", "sequence": 1}
    assert "mocap.cs.cmu.edu" in wash["citation"]
    walk = records["cmu_expmap_train_walking_extra_13"]["labels"]["content"]
    assert walk == "walking"
    assert records["cmu_expmap_train_walking_1"]["labels"]["take"] == "02_01"  # CMU_TAKES
    said = (out / "texts" / "cmu_expmap_test_washwindow_1.txt").read_text()
    assert "window" in said and len(said.splitlines()) == 4
    joints = np.load(out / "new_joints" / "cmu_expmap_train_walking_1.npy")
    assert joints.shape[1:] == (22, 3) and joints[..., 1].min() == pytest.approx(0.0, abs=0.05)


def test_the_command_line_and_contents(release, tmp_path, capsys):
    out = tmp_path / "cli"
    assert main(["data", "import", "--corpus", "cmu-expmap", str(release), "--out", str(out),
                 "--contents", "washwindow", "--quiet"]) == 0
    assert "imported 1 clip(s) as 1 motion(s)" in capsys.readouterr().out
    assert main(["data", "check", str(out)]) == 0


def test_a_folder_without_the_sets_files_is_one_error(tmp_path):
    (tmp_path / "swimming").mkdir()
    (tmp_path / "swimming" / "swimming_1.txt").write_text("0\n")
    with pytest.raises(MlctError, match="no sequence of the CMU expmap set"):
        import_corpus("cmu-expmap", tmp_path, tmp_path / "out")


def test_every_action_has_wordings_with_known_verbs():
    rng = np.random.default_rng(0)
    for action, phrases in ACTIONS.items():
        for phrase in phrases:
            for verb in __import__("re").findall(r"<(\w+)>", phrase):
                assert verb in FORMS, (action, verb)
        said = CMU_EXPMAP.caption({"content": action}, rng, 3)
        assert len(said) == 3 and all(s.endswith(".") and "<" not in s for s in said)
