"""`mlct data import`: own joints or BVH files + captions -> a clean dataset in the standard
layout, or one line saying what is wrong and no output at all."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mlct.cli import main
from mlct.data.captions import pos_tag, tag_caption
from mlct.data.check import check_dataset
from mlct.data.importer import (
    guess_scale,
    import_dataset,
    parse_split,
    read_captions,
    resample,
    split_clips,
    windows,
)
from mlct.data.layout import DatasetLayout
from mlct.data.synth.build import make_motion
from mlct.errors import MlctError
from mlct.motion.bvh import write_bvh
from mlct.motion.skeleton import HUMANML3D, KIT

pytestmark = pytest.mark.usefixtures("one_thread")

CLIPS = {"walk": 1, "jump": 2, "wave": 5}  # name -> procedural benchmark motion


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """Joint and BVH directories of the same clips (one long enough to be cut), and captions."""
    root = tmp_path_factory.mktemp("source")
    (root / "npy").mkdir()
    (root / "bvh").mkdir()
    joints = {name: make_motion(index, seed=0, skeleton=HUMANML3D).joints.astype(np.float64)
              for name, index in CLIPS.items()}
    joints["long"] = np.concatenate([joints["walk"], joints["walk"][::-1], joints["walk"]])
    for name, array in joints.items():
        np.save(root / "npy" / f"{name}.npy", array)
        write_bvh(root / "bvh" / f"{name}.bvh", array, HUMANML3D, HUMANML3D.fps)
    (root / "captions.csv").write_text(
        "name,caption\n"
        "walk,a person walks forward\n"
        'walk.npy,"someone strolls ahead, slowly"\n'
        "jump,a person jumps in place\n"
        "wave,a man waves with his right hand\n"
        "long,a person walks forward then back\n", encoding="utf-8")
    return root, joints


def read_names(path) -> list[str]:
    return [line for line in path.read_text().splitlines() if line]


def test_joints_import_from_the_command_line_is_a_clean_dataset(source, tmp_path, capsys):
    root, joints = source
    out = tmp_path / "data"
    code = main(["data", "import", "--joints", str(root / "npy"), "--captions",
                 str(root / "captions.csv"), "--out", str(out), "--quiet"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "imported 4 clip(s)" in printed and "x 1 to m" in printed
    assert check_dataset(out) == []

    layout = DatasetLayout(out)
    mean, std = layout.load_mean_std(HUMANML3D)
    assert mean.shape == std.shape == (263,) and (std > 0).all()
    names = read_names(out / "all.txt")
    assert sorted(names) == layout.feature_names()
    parts = [set(read_names(out / f"{split}.txt")) for split in ("train", "val", "test")]
    assert sum(len(p) for p in parts) == len(names) and set().union(*parts) == set(names)
    # The long clip is cut into windows inside the length filter, all in one split.
    long_names = [n for n in names if n.startswith("long_")]
    assert len(long_names) >= 2
    assert sum(any(n in p for n in long_names) for p in parts) == 1
    for name in names:
        assert HUMANML3D.min_frames <= len(layout.load_features(name)) < HUMANML3D.max_frames
    records = layout.read_texts("walk")
    assert [r.caption for r in records] == ["a person walks forward",
                                           "someone strolls ahead, slowly"]
    assert records[0].tokens == ("a/DET", "person/NOUN", "walk/VERB", "forward/ADV")
    # The imported motion is the clip, processed: same length and bone lengths of the target.
    walk = layout.load_joints("walk")
    assert len(walk) == len(joints["walk"]) - 1
    thigh = np.linalg.norm(walk[:, 4] - walk[:, 1], axis=-1)
    np.testing.assert_allclose(thigh, HUMANML3D.bone_lengths[4], rtol=1e-3)


def test_bvh_import_gives_the_same_motions(source, tmp_path):
    root, _ = source
    from_npy = import_dataset(tmp_path / "a", root / "captions.csv", joints_dir=root / "npy")
    from_bvh = import_dataset(tmp_path / "b", root / "captions.csv", bvh_dir=root / "bvh")
    assert from_bvh.scale == 0.01  # our BVH files are in centimetres
    assert from_bvh.motions == from_npy.motions and from_bvh.frames == from_npy.frames
    assert check_dataset(tmp_path / "b") == []
    a, b = DatasetLayout(tmp_path / "a"), DatasetLayout(tmp_path / "b")
    for name in a.joint_names():
        error = np.linalg.norm(a.load_joints(name) - b.load_joints(name), axis=-1).max()
        assert error < 0.01, name  # metres: what the BVH round trip keeps (module bvh)


def test_bvh_with_other_joint_names_needs_a_joint_map(source, tmp_path):
    root, joints = source
    renamed = tmp_path / "renamed"
    renamed.mkdir()
    text = (root / "bvh" / "jump.bvh").read_text()
    mapping = {}
    for name in HUMANML3D.joint_names:
        theirs = "mixamo_" + "".join(part.title() for part in name.split("_"))
        text = text.replace(f"ROOT {name}\n", f"ROOT {theirs}\n").replace(
            f"JOINT {name}\n", f"JOINT {theirs}\n")
        mapping[theirs] = name
    (renamed / "jump.bvh").write_text(text)
    (tmp_path / "map.json").write_text(json.dumps(mapping))
    captions = root / "captions.csv"
    with pytest.raises(MlctError, match="no joint for pelvis.*--joint-map"):
        import_dataset(tmp_path / "x", captions, bvh_dir=renamed, skip_uncaptioned=True)
    assert not (tmp_path / "x").exists()
    summary = import_dataset(tmp_path / "y", captions, bvh_dir=renamed, joint_map=tmp_path /
                             "map.json", scale=0.01, skip_uncaptioned=True)
    assert summary.motions == 1 and summary.unused_captions == ["long", "walk", "wave"]
    assert check_dataset(tmp_path / "y") == []


def test_kit_bvh_at_another_frame_rate(tmp_path):
    # A KIT motion written at 25 fps (twice the dataset's 12.5): resampled on import.
    joints = make_motion(0, seed=0, skeleton=KIT).joints.astype(np.float64)
    fine = resample(joints, KIT.fps, 2 * KIT.fps)
    (tmp_path / "bvh").mkdir()
    write_bvh(tmp_path / "bvh" / "kick.bvh", fine, KIT, 2 * KIT.fps)
    (tmp_path / "c.jsonl").write_text(json.dumps({"name": "kick", "captions": [
        "a person kicks", "someone kicks with the left leg"]}) + "\n")
    summary = import_dataset(tmp_path / "kit", tmp_path / "c.jsonl", bvh_dir=tmp_path / "bvh",
                             skeleton="kit")
    assert summary.scale == 10.0  # centimetres in the file, millimetres in KIT-ML
    assert check_dataset(tmp_path / "kit") == []
    assert summary.frames == len(joints) - 1
    features = DatasetLayout(tmp_path / "kit").load_features("kick", KIT)
    assert features.shape == (len(joints) - 1, 251)


def test_resample_interpolates_in_time():
    t = np.arange(31, dtype=np.float64) / 30.0  # 1 s at 30 fps, x = t
    positions = np.zeros((31, 2, 3))
    positions[:, :, 0] = t[:, None]
    out = resample(positions, 30.0, 20.0)
    assert out.shape == (21, 2, 3)
    np.testing.assert_allclose(out[:, 0, 0], np.arange(21) / 20.0, atol=1e-12)
    assert resample(positions, 30.0, 30.0) is positions


def test_windows_cut_long_clips_and_drop_short_ones():
    assert windows(HUMANML3D.min_frames, HUMANML3D) == []  # 39 feature frames: too short
    assert windows(101, HUMANML3D) == [(0, 101)]
    spans = windows(601, HUMANML3D)  # 600 feature frames -> 4 windows of 150
    assert spans == [(0, 151), (150, 301), (300, 451), (450, 601)]
    for start, stop in windows(5000, KIT):
        assert KIT.min_frames <= stop - start - 1 < KIT.max_frames


def test_splits_are_seeded_and_partition_the_clips():
    clips = [f"c{i}" for i in range(50)]
    split = split_clips(clips, (0.8, 0.1, 0.1), seed=3)
    assert [len(split[k]) for k in ("train", "val", "test")] == [40, 5, 5]
    assert sorted(sum(split.values(), [])) == sorted(clips)
    assert split == split_clips(clips, (0.8, 0.1, 0.1), seed=3)
    assert split != split_clips(clips, (0.8, 0.1, 0.1), seed=4)
    assert parse_split("0.7,0.2,0.1") == (0.7, 0.2, 0.1)
    for bad in ("0.8,0.1", "0.8,0.3,0.1", "a,b,c", "1.2,-0.1,-0.1"):
        with pytest.raises(MlctError, match="--split"):
            parse_split(bad)


def test_units_are_guessed_or_refused():
    assert guess_scale([150.0, 160.0], HUMANML3D) == 0.01  # centimetres
    assert guess_scale([1.5], HUMANML3D) == 1.0
    assert guess_scale([1.55], KIT) == 1000.0  # metres -> KIT's millimetres
    with pytest.raises(MlctError, match="pass --scale"):
        guess_scale([59.0], HUMANML3D)  # inches: no power of ten makes a body of it


def test_captions_are_tagged_like_the_benchmark_and_beyond_it():
    assert tag_caption("a person walks forward") == pos_tag("a person walks forward")
    tags = tag_caption("the man catches a ball and tosses it, 3 times")
    assert tags[:4] == [("the", "DET"), ("man", "NOUN"), ("catch", "VERB"), ("a", "DET")]
    assert ("toss", "VERB") in tags and ("3", "NUM") not in tags
    assert all(word.isalpha() for word, _ in tags)


def test_jsonl_and_csv_captions(tmp_path):
    (tmp_path / "c.jsonl").write_text('{"name": "a.bvh", "caption": "a person sits"}\n\n'
                                      '{"name": "b", "captions": ["x jumps", "y  hops\\n"]}\n')
    assert read_captions(tmp_path / "c.jsonl") == {"a": ["a person sits"],
                                                   "b": ["x jumps", "y hops"]}
    (tmp_path / "c.csv").write_text("\ufeffName,Caption,extra\na,a person sits,1\n",
                                    encoding="utf-8")
    assert read_captions(tmp_path / "c.csv") == {"a": ["a person sits"]}


@pytest.mark.parametrize("filename, text, message", [
    ("c.csv", "file,text\nwalk,a person walks\n", "c.csv:1: the header must name"),
    ("c.jsonl", '{"name": "walk", "caption": "a walk"}\n{oops\n', "c.jsonl:2: not JSON"),
    ("c.jsonl", '{"name": "walk"}\n', "c.jsonl:1: needs 'caption'"),
    ("c.csv", "name,caption\nwalk,a person # walks\n", "c.csv:2: a caption may not contain '#'"),
    ("c.csv", "name,caption\nwalk,\n", "c.csv:2: empty caption"),
    ("c.txt", "walk a person walks\n", "must be a .csv"),
])
def test_bad_captions_file_is_one_line_and_writes_nothing(source, tmp_path, capsys, filename,
                                                          text, message):
    root, _ = source
    (tmp_path / filename).write_text(text)
    code = main(["data", "import", "--joints", str(root / "npy"), "--captions",
                 str(tmp_path / filename), "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not (tmp_path / "out").exists()


def test_missing_captions_are_listed_or_skipped(source, tmp_path, capsys):
    root, _ = source
    (tmp_path / "c.csv").write_text("name,caption\nwalk,a person walks\n")
    args = ["data", "import", "--joints", str(root / "npy"), "--captions",
            str(tmp_path / "c.csv"), "--out", str(tmp_path / "out"), "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "3 motion file(s) have no caption" in err and "jump, long, wave" in err
    assert not (tmp_path / "out").exists()
    assert main(args + ["--skip-uncaptioned"]) == 0
    assert "skipped 3 uncaptioned file(s): jump, long, wave" in capsys.readouterr().out
    assert read_names(tmp_path / "out" / "all.txt") == ["walk"]


def test_a_nan_clip_stops_the_import_and_leaves_nothing(source, tmp_path, capsys):
    root, joints = source
    clips = tmp_path / "npy"
    clips.mkdir()
    for name in ("walk", "wave"):
        np.save(clips / f"{name}.npy", joints[name])
    broken = joints["wave"].copy()
    broken[10, 3] = np.nan
    np.save(clips / "wave.npy", broken)  # processed after walk: the import is half done
    code = main(["data", "import", "--joints", str(clips), "--captions",
                 str(root / "captions.csv"), "--out", str(tmp_path / "out"), "--scale", "1",
                 "--skip-uncaptioned", "--quiet"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "wave.npy" in err and "NaN" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["npy"]  # no output, no partial dir


def test_short_clips_are_skipped_and_reported(tmp_path):
    (tmp_path / "npy").mkdir()
    joints = make_motion(1, seed=0, skeleton=HUMANML3D).joints
    np.save(tmp_path / "npy" / "ok.npy", joints)
    np.save(tmp_path / "npy" / "blip.npy", joints[:20])
    (tmp_path / "c.csv").write_text("name,caption\nok,a person walks\nblip,a person waits\n")
    summary = import_dataset(tmp_path / "out", tmp_path / "c.csv", joints_dir=tmp_path / "npy")
    assert summary.skipped_short == ["blip"] and summary.motions == 1
    assert check_dataset(tmp_path / "out") == []


def test_existing_output_is_kept_without_overwrite(source, tmp_path):
    root, _ = source
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(MlctError, match="--overwrite"):
        import_dataset(out, root / "captions.csv", joints_dir=root / "npy")
    assert (out / "keep.txt").read_text() == "mine"
