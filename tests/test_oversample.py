"""`mlct data oversample`: a copy of a labelled dataset whose training split lists chosen
families' motions several times, everything else unchanged."""

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
from mlct.data.oversample import families_of, oversample_dataset
from mlct.errors import MlctError
from test_everyday import make_benchmark


def single_family(src: Path) -> str:
    """A family that some training motion of the benchmark shows alone."""
    labels = read_labels(src)
    for name in DatasetLayout.existing(src).read_split("train"):
        if len(families_of(labels[name])) == 1:
            return families_of(labels[name])[0]
    raise AssertionError("the benchmark has no single-action training motion")


def test_oversample_lists_the_chosen_motions_times_and_keeps_the_rest(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    family = single_family(src)
    summary = oversample_dataset(src, tmp_path / "focus", [family], times=3)
    labels = read_labels(src)
    train = DatasetLayout.existing(src).read_split("train")
    chosen = {n for n in train if families_of(labels[n]) == [family]}
    listed = Counter(DatasetLayout.existing(tmp_path / "focus").read_split("train"))
    assert summary == {"chosen": len(chosen), "items": len(train) + 2 * len(chosen)}
    assert {n: c for n, c in listed.items() if c > 1} == {n: 3 for n in chosen}
    assert set(listed) == set(train)
    for f in ("Mean.npy", "Std.npy", "labels.jsonl", "test.txt"):
        assert (tmp_path / "focus" / f).read_bytes() == (src / f).read_bytes()
    focus = DatasetLayout.existing(tmp_path / "focus")
    for name in train:
        np.testing.assert_array_equal(focus.load_features(name),
                                      DatasetLayout.existing(src).load_features(name))
    meta = json.loads((tmp_path / "focus" / "synth.json").read_text())
    assert meta["oversampled"]["families"] == [family] and meta["oversampled"]["times"] == 3
    # the training set reads the repeats as items: batches see the family three times as often
    items = Text2MotionDataset(tmp_path / "focus", "train")
    assert len(items) == len(Text2MotionDataset(src, "train")) + 2 * len(chosen)


def test_oversample_with_sequences_takes_motions_where_the_family_is_one_of_several(
        tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    labels = read_labels(src)
    train = DatasetLayout.existing(src).read_split("train")
    family = Counter(f for n in train for f in families_of(labels[n])).most_common(1)[0][0]
    alone = oversample_dataset(src, tmp_path / "a", [family], times=2)["chosen"]
    anywhere = oversample_dataset(src, tmp_path / "b", [family], times=2,
                                  single_only=False)["chosen"]
    assert anywhere == sum(family in families_of(labels[n]) for n in train) >= alone


def test_oversample_refuses_bad_input_and_leaves_nothing(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    family = single_family(src)
    with pytest.raises(MlctError, match="no motion shows cartwheel"):
        oversample_dataset(src, tmp_path / "focus", ["cartwheel"])
    with pytest.raises(MlctError, match="--times"):
        oversample_dataset(src, tmp_path / "focus", [family], times=1)
    with pytest.raises(MlctError, match="split 'nope'"):
        oversample_dataset(src, tmp_path / "focus", [family], split="nope")
    with pytest.raises(MlctError, match="must differ"):
        oversample_dataset(src, src, [family])
    assert not (tmp_path / "focus").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".focus")]


def test_cli_oversample_exit_codes(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    base = [sys.executable, "-m", "mlct.cli", "data", "oversample", str(src), "--out"]
    run = base + [str(tmp_path / "focus"), "--families"]
    ok = subprocess.run(run + [single_family(src)], capture_output=True, text=True)
    assert ok.returncode == 0 and "listed 3 times" in ok.stdout
    again = subprocess.run(run + [single_family(src)], capture_output=True, text=True)
    assert again.returncode == 2 and "exists" in again.stderr and "Traceback" not in again.stderr
    bad = subprocess.run(base + [str(tmp_path / "x"), "--families", "cartwheel"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "cartwheel" in bad.stderr and "Traceback" not in bad.stderr


def test_check_accepts_the_repeats_of_an_oversampled_split_only(tmp_path: Path) -> None:
    from mlct.data.check import check_dataset

    src = make_benchmark(tmp_path)
    oversample_dataset(src, tmp_path / "focus", [single_family(src)], times=3)
    assert not [p for p in check_dataset(tmp_path / "focus") if p.kind == "duplicate"]
    # a repeat in a split that was not oversampled is still a problem
    val = tmp_path / "focus" / "val.txt"
    first = val.read_text().split()[0]
    val.write_text(val.read_text() + first + "\n")
    assert [p.path for p in check_dataset(tmp_path / "focus") if p.kind == "duplicate"] == [val]
