"""`mlct data merge`: one dataset from several, names kept apart, splits joined, the first's
normalization."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from mlct.data.dataset import Text2MotionDataset
from mlct.data.labels import read_labels
from mlct.data.layout import DatasetLayout
from mlct.data.merge import merge_datasets
from mlct.data.oversample import oversample_dataset
from mlct.data.synth.build import synthesize_dataset
from mlct.errors import MlctError


def two_benchmarks(root: Path) -> tuple[Path, Path]:
    synthesize_dataset(root / "a", num=10, seed=0, progress=False)
    synthesize_dataset(root / "b", num=8, seed=1, progress=False)
    return root / "a", root / "b"


def test_merge_keeps_every_motion_under_its_own_name(tmp_path: Path) -> None:
    a, b = two_benchmarks(tmp_path)
    summary = merge_datasets([a, b], tmp_path / "ab")
    merged, la, lb = (DatasetLayout.existing(p) for p in (tmp_path / "ab", a, b))
    assert summary["motions"] == [10, 8]
    for split in ("train", "val", "test", "all"):
        assert merged.read_split(split) == la.read_split(split) + [
            f"d2_{n}" for n in lb.read_split(split)]
    # the same names exist in both sources (seed 0 and 1 both number from 000000): both kept
    name = la.read_split("all")[0]
    assert name in lb.read_split("all")
    np.testing.assert_array_equal(merged.load_features(name), la.load_features(name))
    np.testing.assert_array_equal(merged.load_features(f"d2_{name}"), lb.load_features(name))
    assert ([t.caption for t in merged.read_texts(f"d2_{name}")]
            == [t.caption for t in lb.read_texts(name)])
    labels = read_labels(tmp_path / "ab")
    assert labels[f"d2_{name}"]["actions"] == read_labels(b)[name]["actions"]
    assert len(labels) == 18
    for f in ("Mean.npy", "Std.npy"):
        assert (tmp_path / "ab" / f).read_bytes() == (a / f).read_bytes()
    meta = json.loads((tmp_path / "ab" / "synth.json").read_text())
    assert [m["prefix"] for m in meta["merged"]] == ["", "d2_"] and "seed" not in meta
    assert len(Text2MotionDataset(tmp_path / "ab", "train")) == (
        len(Text2MotionDataset(a, "train")) + len(Text2MotionDataset(b, "train")))


def test_merge_keeps_an_oversampled_split_oversampled(tmp_path: Path) -> None:
    a, b = two_benchmarks(tmp_path)
    labels = read_labels(b)
    family = labels[DatasetLayout.existing(b).read_split("train")[0]]["actions"][0]["family"]
    oversample_dataset(b, tmp_path / "b3", [family], times=3, single_only=False)
    merge_datasets([a, tmp_path / "b3"], tmp_path / "ab")
    counts = Counter(DatasetLayout.existing(tmp_path / "ab").read_split("train"))
    assert max(counts.values()) == 3 and all(n.startswith("d2_") for n, c in counts.items()
                                             if c > 1)


def test_merge_refuses_bad_input_and_leaves_nothing(tmp_path: Path) -> None:
    a, b = two_benchmarks(tmp_path)
    with pytest.raises(MlctError, match="two or more"):
        merge_datasets([a], tmp_path / "ab")
    with pytest.raises(MlctError, match="named twice"):
        merge_datasets([a, a], tmp_path / "ab")
    with pytest.raises(MlctError, match="must differ"):
        merge_datasets([a, b], a)
    with pytest.raises(MlctError, match="not a dataset"):
        merge_datasets([a, tmp_path], tmp_path / "ab")
    kit = tmp_path / "kit"
    synthesize_dataset(kit, num=4, seed=0, skeleton="kit", progress=False)
    with pytest.raises(MlctError, match="different feature widths"):
        merge_datasets([a, kit], tmp_path / "ab")
    (b / "synth.json").write_text("{not json")
    with pytest.raises(MlctError, match="synth.json: not readable JSON"):
        merge_datasets([a, b], tmp_path / "ab")
    synthesize_dataset(tmp_path / "c", num=3, seed=2, progress=False)
    name = DatasetLayout.existing(a).read_split("all")[0]
    for folder in ("new_joint_vecs", "new_joints", "texts"):  # a first source with a d2_ name
        for f in (a / folder).glob(f"{name}.*"):
            (a / folder / f"d2_{f.name}").write_bytes(f.read_bytes())
    with pytest.raises(MlctError, match="two sources give"):
        merge_datasets([a, tmp_path / "c"], tmp_path / "ab")
    assert not (tmp_path / "ab").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".ab")]


def test_cli_merge_exit_codes(tmp_path: Path) -> None:
    a, b = two_benchmarks(tmp_path)
    run = [sys.executable, "-m", "mlct.cli", "data", "merge", str(a), str(b), "--out",
           str(tmp_path / "ab")]
    ok = subprocess.run(run, capture_output=True, text=True)
    assert ok.returncode == 0 and "18 motions from 2 datasets" in ok.stdout, ok.stderr
    again = subprocess.run(run, capture_output=True, text=True)
    assert again.returncode == 2 and "exists" in again.stderr and "Traceback" not in again.stderr


def test_check_accepts_a_merged_oversampled_split(tmp_path: Path) -> None:
    from mlct.data.check import check_dataset

    a, b = two_benchmarks(tmp_path)
    family = read_labels(b)[DatasetLayout.existing(b).read_split("train")[0]]["actions"][0][
        "family"]
    oversample_dataset(b, tmp_path / "b3", [family], times=3, single_only=False)
    merge_datasets([a, tmp_path / "b3"], tmp_path / "ab")
    assert json.loads((tmp_path / "ab" / "synth.json").read_text())["repeating_splits"] == [
        "train"]
    assert not [p for p in check_dataset(tmp_path / "ab") if p.kind == "duplicate"]
