"""The dataset checker: each rule, planted alone, yields exactly its problem."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from dataset_factory import CAPTIONS, make_dataset, write_motion

from mlct.data.check import Problem, check_dataset
from mlct.errors import MlctError
from mlct.motion.skeleton import KIT

EXTRA = "000005"  # a motion in no split, so that planting a problem there touches no split rule


@pytest.fixture
def root(tmp_path):
    make_dataset(tmp_path)
    write_motion(tmp_path, EXTRA, 64, seed=5)
    assert check_dataset(tmp_path) == []
    return tmp_path


def only(problems: list[Problem]) -> Problem:
    """The one problem found (fails, listing them, if there are more or none)."""
    assert len(problems) == 1, "\n".join(map(str, problems))
    return problems[0]


def features(root, name=EXTRA):
    return root / "new_joint_vecs" / f"{name}.npy"


def joints(root, name=EXTRA):
    return root / "new_joints" / f"{name}.npy"


def text(root, name=EXTRA):
    return root / "texts" / f"{name}.txt"


def test_problem_prints_one_line(tmp_path):
    assert str(Problem(tmp_path / "a.npy", "bad", "x")) == f"{tmp_path / 'a.npy'}: bad"
    assert str(Problem(tmp_path / "a.txt", "bad", "x", line=3)) == f"{tmp_path / 'a.txt'}:3: bad"


def test_missing_directory(root):
    shutil.rmtree(root / "new_joints")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("missing_dir", root / "new_joints")


def test_features_without_text(root):
    text(root).unlink()
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("missing_text", features(root))
    assert "texts" in problem.message


def test_text_without_features(root):
    text(root, "000077").write_text(CAPTIONS[0] + "\n")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("orphan_text", text(root, "000077"))


def test_features_without_joints(root):
    joints(root).unlink()
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("missing_joints", features(root))


def test_joints_without_features(root):
    shutil.copy(joints(root), joints(root, "000077"))
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("orphan_joints", joints(root, "000077"))


def test_truncated_npy(root):
    path = features(root)
    path.write_bytes(path.read_bytes()[:-100])
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("unreadable", path)
    assert "unreadable .npy" in problem.message


def test_garbage_and_undecodable_files_do_not_raise(root):
    joints(root).write_bytes(b"\x93NUMPY garbage")
    text(root).write_bytes(b"\xff\xfe\xfa")
    kinds = sorted(p.kind for p in check_dataset(root))
    assert kinds == ["unreadable", "unreadable"]


def test_wrong_width_against_majority(root):
    np.save(features(root), np.zeros((64, 262), dtype=np.float32))
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("width", features(root))
    assert problem.message == "262 features per frame, expected 263"


def test_wrong_width_against_given_skeleton(root):
    problems = check_dataset(root, skeleton=KIT)
    widths = [p for p in problems if p.kind == "width"]
    assert len(widths) == 6 and all("expected 251" in p.message for p in widths)


def test_features_not_2d(root):
    np.save(features(root), np.zeros((64, 263, 1), dtype=np.float32))
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("shape", features(root))


def test_joints_wrong_joint_count(root):
    np.save(joints(root), np.zeros((64, 21, 3), dtype=np.float32))
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("shape", joints(root))
    assert problem.message == "21 joints, expected 22"


def test_joints_frame_count_differs_from_features(root):
    np.save(joints(root), np.load(joints(root))[:-1])
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("frames_mismatch", joints(root))
    assert problem.message == "63 frames, but the features have 64"


@pytest.mark.parametrize("which", ["features", "joints"])
def test_nan_and_inf(root, which):
    path = features(root) if which == "features" else joints(root)
    array = np.load(path)
    array.reshape(-1)[[3, 7]] = [np.nan, np.inf]
    np.save(path, array)
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("nonfinite", path)
    assert problem.message == "1 NaN and 1 inf values"


@pytest.mark.parametrize("line, message", [
    ("", "empty line"),
    ("a man walks.", "expected 4"),
    ("#a/DET#0.0#0.0", "empty caption"),
    ("a man walks.#a DET#0.0#0.0", "is not word/POS"),
    ("a man walks.#a/DET#x#0.0", "is not a number"),
    ("a man walks.#a/DET#2.0#1.0", "is not after start"),
])
def test_ill_formed_text_line(root, line, message):
    text(root).write_text(f"{CAPTIONS[0]}\n{line}\n{CAPTIONS[1]}\n")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path, problem.line) == ("text", text(root), 2)
    assert message in problem.message


def test_empty_text_file(root):
    text(root).write_text("")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("text", text(root))


@pytest.mark.parametrize("frames", [39, 200])
def test_motion_length_out_of_range(root, frames):
    write_motion(root, EXTRA, frames)
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("length", features(root))
    assert problem.message.startswith(f"{frames} frames: outside the humanml3d length filter "
                                      f"40..199")


@pytest.mark.parametrize("span, message", [
    ("0.5#2.0", "30 frames"),  # frames 10..39: shorter than 40
    ("1.0#3.5", "ends after the motion (64 frames)"),  # frames 20..69 of 64
])
def test_subclip_out_of_range(root, span, message):
    text(root).write_text(f"{CAPTIONS[0]}\na man walks.#a/DET man/NOUN#{span}\n")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path, problem.line) == ("length", text(root), 2)
    assert message in problem.message


def test_subclip_in_range_is_fine(root):
    text(root).write_text(f"{CAPTIONS[0]}\na man walks.#a/DET man/NOUN#0.5#3.0\n")
    assert check_dataset(root) == []


def test_missing_split_file(root):
    (root / "val.txt").unlink()
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("missing_split", root / "val.txt")


def test_split_entry_without_files(root):
    with open(root / "train.txt", "a") as f:
        f.write("ghost\n")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path, problem.line) == ("split_entry", root / "train.txt", 4)
    assert "ghost.npy" in problem.message and "ghost.txt" in problem.message


def test_split_entry_without_text(root):
    (root / "test.txt").write_text(f"{EXTRA}\n")
    text(root).unlink()
    kinds = sorted(p.kind for p in check_dataset(root))
    assert kinds == ["missing_text", "split_entry"]


def test_duplicate_split_entry(root):
    (root / "val.txt").write_text("000003\n000003\n")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path, problem.line) == ("duplicate", root / "val.txt", 2)
    assert "first on line 1" in problem.message


def test_optional_split_checked_too(root):
    (root / "all.txt").write_text("000001\nghost\n")
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path, problem.line) == ("split_entry", root / "all.txt", 2)


def test_mean_std_missing(root):
    (root / "Std.npy").unlink()
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("mean_std", root / "Std.npy")


def test_mean_wrong_shape(root):
    np.save(root / "Mean.npy", np.zeros(251, dtype=np.float32))
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("mean_std", root / "Mean.npy")
    assert problem.message == "251 values, expected 263"


def test_std_zero(root):
    std = np.load(root / "Std.npy")
    std[259:] = 0.0
    np.save(root / "Std.npy", std)
    problem = only(check_dataset(root))
    assert (problem.kind, problem.path) == ("mean_std", root / "Std.npy")
    assert problem.message.startswith("4 std values <= 0")


def test_width_matching_no_skeleton(tmp_path):
    for name in ("a", "b"):
        (tmp_path / "new_joint_vecs").mkdir(exist_ok=True)
        np.save(tmp_path / "new_joint_vecs" / f"{name}.npy", np.zeros((50, 100), np.float32))
    problems = check_dataset(tmp_path)
    assert [p.kind for p in problems if p.path == tmp_path / "new_joint_vecs"] == ["skeleton"]


def test_kit_dataset_is_clean(tmp_path):
    make_dataset(tmp_path, {"000001": 24, "000002": 199, "000003": 50, "000004": 30},
                 skeleton=KIT)
    assert check_dataset(tmp_path) == []
    assert check_dataset(tmp_path, skeleton="kit") == []


def test_problems_sorted_by_file(root):
    text(root).write_text("bad\n")
    shutil.copy(joints(root), joints(root, "000077"))
    (root / "Mean.npy").unlink()
    paths = [str(p.path) for p in check_dataset(root)]
    assert paths == sorted(paths) and len(paths) == 3


def test_bad_usage_raises(tmp_path):
    with pytest.raises(MlctError, match="no such directory"):
        check_dataset(tmp_path / "missing")
    with pytest.raises(MlctError, match="unknown skeleton"):
        check_dataset(tmp_path, skeleton="horse")


def test_empty_directory_lists_what_is_missing(tmp_path):
    kinds = sorted(p.kind for p in check_dataset(tmp_path))
    assert kinds == ["mean_std"] * 2 + ["missing_dir"] * 3 + ["missing_split"] * 3
