"""The standard dataset layout: caption lines, splits, array loading and validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from dataset_factory import CAPTIONS, make_dataset

from mlct.data.captions import TextLineError, parse_text_line
from mlct.data.layout import (
    BadFileError,
    DatasetLayout,
    is_mirrored,
    load_npy,
    read_split,
    read_texts,
    resolve_skeleton,
)
from mlct.errors import MlctError
from mlct.motion.skeleton import HUMANML3D, KIT


def test_parse_real_line():
    record = parse_text_line(CAPTIONS[0] + "\n")
    assert record.caption == "a man kicks something or someone with his left leg."
    assert record.tokens[:3] == ("a/DET", "man/NOUN", "kick/VERB")
    assert len(record.tokens) == 10
    assert record.words[:3] == ("a", "man", "kick")
    assert record.whole_clip and record.frame_span(20.0) is None


def test_nan_times_mean_whole_clip():
    record = parse_text_line("a man walks.#a/DET man/NOUN walk/VERB#nan#nan")
    assert record.whole_clip and (record.start, record.end) == (0.0, 0.0)


def test_subclip_frames_at_skeleton_fps():
    record = parse_text_line("a man walks.#a/DET man/NOUN walk/VERB#1.0#3.3")
    assert not record.whole_clip
    assert record.frame_span(HUMANML3D.fps) == (20, 66)  # int(1.0*20), int(3.3*20)
    assert record.frame_span(KIT.fps) == (12, 41)  # int(12.5), int(41.25)


def test_word_containing_slash_keeps_last_tag():
    record = parse_text_line("up and/or down#up/ADV and/or/CCONJ down/ADV#0.0#0.0")
    assert record.words == ("up", "and/or", "down")


@pytest.mark.parametrize("line, message", [
    ("", "empty line"),
    ("   ", "empty line"),
    ("a man walks.#a/DET man/NOUN walk/VERB#0.0", "expected 4"),
    ("a man walks.#a/DET#0.0#0.0#extra", "expected 4"),
    ("#a/DET man/NOUN#0.0#0.0", "empty caption"),
    ("a man walks.##0.0#0.0", "no word/POS tokens"),
    ("a man walks.#a/DET man walk/VERB#0.0#0.0", "'man' is not word/POS"),
    ("a man walks.#a/DET /NOUN#0.0#0.0", "is not word/POS"),
    ("a man walks.#a/DET man/#0.0#0.0", "is not word/POS"),
    ("a man walks.#a/DET#zero#0.0", "start time 'zero' is not a number"),
    ("a man walks.#a/DET#0.0#inf", "end time 'inf' is not a finite"),
    ("a man walks.#a/DET#-1.0#2.0", "start time '-1.0'"),
    ("a man walks.#a/DET#3.0#2.0", "end 2 s is not after start 3 s"),
    ("a man walks.#a/DET#2.0#2.0", "is not after start"),
])
def test_ill_formed_lines(line, message):
    with pytest.raises(TextLineError, match=message):
        parse_text_line(line)


def test_read_texts_names_file_and_line(tmp_path):
    path = tmp_path / "000001.txt"
    path.write_text(CAPTIONS[0] + "\nbroken line\n", encoding="utf-8")
    with pytest.raises(BadFileError) as info:
        read_texts(path)
    assert str(info.value).startswith(f"{path}:2: expected 4")
    assert info.value.line == 2 and info.value.path == path


def test_read_texts_empty_and_undecodable(tmp_path):
    empty = tmp_path / "empty.txt"
    empty.write_text("", encoding="utf-8")
    with pytest.raises(BadFileError, match="no captions"):
        read_texts(empty)
    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"\xff\xfe\x00caption")
    with pytest.raises(BadFileError, match="cannot read"):
        read_texts(binary)


def test_read_split_order_and_blank_lines(tmp_path):
    path = tmp_path / "train.txt"
    path.write_text("000002\n\n000001\r\n  M000001  \n000002\n", encoding="utf-8")
    assert read_split(path) == ["000002", "000001", "M000001", "000002"]


def test_layout_lists_and_loads(tmp_path):
    features = make_dataset(tmp_path)
    # An atomic writer's temporary file and an unrelated file are not motions.
    (tmp_path / "new_joint_vecs" / ".000009.npy.tmp.npy").write_bytes(b"partial")
    (tmp_path / "new_joint_vecs" / "notes.md").write_text("x")
    layout = DatasetLayout(tmp_path)
    assert layout.feature_names() == sorted(features)
    assert layout.joint_names() == sorted(features) == layout.text_names()
    assert layout.splits() == ["train", "val", "test"]
    assert layout.read_split("val") == ["000003"]
    loaded = layout.load_features("000002", HUMANML3D)
    assert loaded.dtype == np.float32 and np.array_equal(loaded, features["000002"])
    assert layout.load_joints("000002", HUMANML3D).shape == (80, 22, 3)
    assert len(layout.read_texts("000002")) == len(CAPTIONS)
    mean, std = layout.load_mean_std(HUMANML3D)
    assert mean.shape == std.shape == (263,)
    assert layout.infer_skeleton() is HUMANML3D
    with pytest.raises(MlctError, match="no such split file"):
        layout.read_split("train_val")


def test_load_validation_names_the_file(tmp_path):
    make_dataset(tmp_path)
    layout = DatasetLayout(tmp_path)
    with pytest.raises(BadFileError, match="263 features per frame, expected 251"):
        layout.load_features("000001", KIT)
    with pytest.raises(BadFileError, match="22 joints, expected 21"):
        layout.load_joints("000001", KIT)
    path = layout.features_path("000002")
    array = np.load(path)
    array[3, 5] = np.nan
    np.save(path, array)
    with pytest.raises(BadFileError, match=r"000002\.npy: 1 NaN and 0 inf values"):
        layout.load_features("000002", HUMANML3D)
    path.write_bytes(path.read_bytes()[:1000])  # truncated
    with pytest.raises(BadFileError, match=r"000002\.npy: unreadable \.npy"):
        layout.load_features("000002")
    with pytest.raises(BadFileError, match="missing"):
        layout.load_features("nope")
    layout.std_path.unlink()
    with pytest.raises(MlctError, match="mlct data stats"):
        layout.load_mean_std(HUMANML3D)


def test_load_npy_refuses_pickles_and_strings(tmp_path):
    objects = tmp_path / "objects.npy"
    np.save(objects, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(BadFileError, match="unreadable"):
        load_npy(objects)
    strings = tmp_path / "strings.npy"
    np.save(strings, np.array(["a", "b"]))
    with pytest.raises(BadFileError, match="not a real number type"):
        load_npy(strings)
    garbage = tmp_path / "garbage.npy"
    garbage.write_bytes(b"this is not numpy")
    with pytest.raises(BadFileError, match="unreadable"):
        load_npy(garbage)


def test_infer_kit_and_resolve(tmp_path):
    make_dataset(tmp_path, {"000001": 30, "000002": 40, "000003": 50}, skeleton=KIT)
    assert DatasetLayout(tmp_path).infer_skeleton() is KIT
    assert DatasetLayout(tmp_path / "nothing").infer_skeleton() is None
    assert resolve_skeleton("kit") is KIT and resolve_skeleton(None) is None
    with pytest.raises(MlctError, match="unknown skeleton"):
        resolve_skeleton("smplx")


def test_mirrored_names():
    assert is_mirrored("M000001") and not is_mirrored("000001")
    assert math.isclose(KIT.fps, 12.5)


@pytest.mark.parametrize("bad", ["../../etc/passwd", "sub/name", "..", ".hidden", "a\\b"])
def test_split_names_cannot_leave_the_dataset(tmp_path, bad) -> None:
    """Names from split files are joined to paths: one that could escape is refused."""
    from mlct.data.layout import read_split

    split = tmp_path / "train.txt"
    split.write_text(f"000001\n{bad}\n")
    with pytest.raises(MlctError, match="line 2: .* is not a motion name"):
        read_split(split)
    split.write_text("000001\nM000002\n\n")
    assert read_split(split) == ["000001", "M000002"]
