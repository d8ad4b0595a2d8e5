"""Mean/Std the HumanML3D way, and the dataset statistics report."""

from __future__ import annotations

import numpy as np
import pytest
from dataset_factory import VOCABULARY, make_dataset, write_motion

from mlct.data.stats import (
    RunningMeanStd,
    dataset_statistics,
    format_statistics,
    group_averaged_std,
    standard_mean_std,
)
from mlct.errors import MlctError
from mlct.motion.skeleton import HUMANML3D, KIT


def reference_mean_std(arrays, joints_num):
    """cal_mean_variance written out independently: concatenate, then average std by group."""
    data = np.concatenate(arrays, axis=0).astype(np.float64)
    mean, std = data.mean(axis=0), data.std(axis=0)
    r = (joints_num - 1) * 3  # ric
    o = (joints_num - 1) * 6  # rotations
    v = joints_num * 3  # local velocities
    bounds = [0, 1, 3, 4, 4 + r, 4 + r + o, 4 + r + o + v, 8 + r + o + v]
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        std[lo:hi] = std[lo:hi].mean()
    return mean, std


def test_running_moments_match_numpy():
    rng = np.random.default_rng(0)
    chunks = [rng.normal(3.0, 2.0, size=(n, 7)) for n in (1, 50, 13, 200)]
    running = RunningMeanStd(7)
    for chunk in chunks:
        running.update(chunk)
    running.update(np.zeros((0, 7)))
    data = np.concatenate(chunks)
    assert running.count == len(data)
    np.testing.assert_allclose(running.mean, data.mean(0), rtol=1e-12)
    np.testing.assert_allclose(running.std, data.std(0), rtol=1e-10)


@pytest.mark.parametrize("skeleton", [HUMANML3D, KIT])
def test_group_averaging_matches_reference(skeleton):
    rng = np.random.default_rng(1)
    # Groups with very different scales, so averaging across a group boundary would show.
    scales = rng.uniform(0.01, 10.0, size=skeleton.feature_dim)
    arrays = [rng.normal(size=(n, skeleton.feature_dim)) * scales for n in (45, 60, 199)]
    mean, std, constant = standard_mean_std(arrays, skeleton)
    ref_mean, ref_std = reference_mean_std(arrays, skeleton.n_joints)
    assert mean.dtype == std.dtype == np.float32 and constant == []
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(std, ref_std, rtol=1e-5)
    assert len(np.unique(std)) == 7  # one value per group


def test_constant_group_gets_std_one():
    std = np.ones(HUMANML3D.feature_dim)
    std[3] = 0.0  # root height constant (e.g. nobody ever jumps)
    averaged, constant = group_averaged_std(std, HUMANML3D)
    assert constant == ["root_height"] and averaged[3] == 1.0


def test_dataset_statistics_writes_reference_mean_std(tmp_path):
    features = make_dataset(tmp_path, mean_std=False)
    # A NaN file is skipped (as in cal_mean_variance) and noted.
    bad = write_motion(tmp_path, "000009", 50, seed=9)
    bad[10, 0] = np.nan
    np.save(tmp_path / "new_joint_vecs" / "000009.npy", bad)
    stats = dataset_statistics(tmp_path)
    ref_mean, ref_std = reference_mean_std(list(features.values()), 22)
    mean, std = np.load(tmp_path / "Mean.npy"), np.load(tmp_path / "Std.npy")
    assert mean.dtype == np.float32 and mean.shape == (263,)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(std, ref_std, rtol=1e-5)
    assert stats["mean_std"]["written"]
    assert any("000009.npy" in note and "NaN" in note for note in stats["notes"])
    assert stats["motions"] == len(features)


def test_dataset_statistics_counts(tmp_path):
    sub = "a man walks.#a/DET man/NOUN walk/VERB#1.0#2.5"
    features = make_dataset(
        tmp_path, {"000001": 60, "M000001": 60, "000002": 30, "000003": 199, "000004": 250},
        captions={"000002": [sub, sub.replace("1.0#2.5", "0.0#0.0")]}, mean_std=False)
    stats = dataset_statistics(tmp_path, skeleton="humanml3d", write_mean_std=False)
    assert stats["skeleton"] == "humanml3d" and stats["feature_dim"] == 263
    assert stats["motions"] == 5 and stats["mirrored"] == 1
    assert stats["frames"] == 599
    assert stats["hours"] == pytest.approx(599 / 20 / 3600)
    assert stats["length"] == {"min": 30, "max": 250, "mean": pytest.approx(599 / 5),
                               "in_range": 3, "min_frames": 40, "max_frames": 200}
    histogram = stats["histogram"]
    assert len(histogram) == 10 and sum(b["count"] for b in histogram) == 5
    assert histogram[0]["lo"] == 30 and histogram[-1]["hi"] > 250
    assert stats["captions"] == 3 * 4 + 2 and stats["subclip_captions"] == 1
    assert stats["text_files"] == 5
    assert stats["vocabulary"] == len(VOCABULARY)
    assert stats["splits"]["train"] == {"names": 3, "with_features": 3, "in_range": 2}
    assert stats["splits"]["test"] == {"names": 1, "with_features": 1, "in_range": 0}
    assert stats["foot_skating_ratio"] == 0.0 and stats["joint_files"] == 5
    assert not stats["mean_std"]["written"] and not (tmp_path / "Mean.npy").exists()
    assert len(features) == 5


def test_skating_ratio_is_the_mean_over_joint_files(tmp_path):
    make_dataset(tmp_path, {"000001": 41, "000002": 41})
    path = tmp_path / "new_joints" / "000002.npy"
    joints = np.load(path)
    toe = HUMANML3D.foot_left[1]
    joints[:, toe, 0] = np.arange(41) / 20.0  # dragged at 1 m/s on the floor: ratio 1
    joints[:, toe, 1] = 0.0
    np.save(path, joints)
    stats = dataset_statistics(tmp_path, write_mean_std=False)
    assert stats["foot_skating_ratio"] == pytest.approx(0.5)


def test_kit_inferred_and_format(tmp_path):
    make_dataset(tmp_path, {"000001": 30, "000002": 50, "000003": 24}, skeleton=KIT)
    stats = dataset_statistics(tmp_path)
    assert stats["skeleton"] == "kit" and stats["length"]["in_range"] == 3
    assert np.load(tmp_path / "Std.npy").shape == (251,)
    text = format_statistics(stats)
    assert "kit, 12.5 fps, 251 features" in text
    assert "vocabulary 16 words" in text
    assert "within the length filter 24..199" in text
    assert "foot-skating ratio 0.0000" in text
    assert text.count("\n  ") >= 10  # ten histogram rows
    assert "Mean/Std   written to" in text


def test_notes_for_bad_files_are_formatted(tmp_path):
    make_dataset(tmp_path)
    (tmp_path / "texts" / "000001.txt").write_text("no fields here\n")
    stats = dataset_statistics(tmp_path, write_mean_std=False)
    text = format_statistics(stats)
    assert "notes (1; `mlct data check` lists every problem)" in text
    assert "000001.txt:1: expected 4" in text


def test_usage_errors(tmp_path):
    with pytest.raises(MlctError, match="no such directory"):
        dataset_statistics(tmp_path / "missing")
    with pytest.raises(MlctError, match="not a dataset in the standard layout"):
        dataset_statistics(tmp_path)
    make_dataset(tmp_path)
    with pytest.raises(MlctError, match="unknown skeleton"):
        dataset_statistics(tmp_path, skeleton="smpl-x")
    for path in (tmp_path / "new_joint_vecs").iterdir():
        path.write_bytes(b"broken")
    with pytest.raises(MlctError, match="no usable feature files"):
        dataset_statistics(tmp_path, skeleton="humanml3d")
