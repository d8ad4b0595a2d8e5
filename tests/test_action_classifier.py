"""The action classifier of the procedural benchmark: classes, training, the directory, metrics."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from mlct.data.synth.build import synthesize_dataset
from mlct.errors import MlctError
from mlct.eval.judge.action_classifier import (
    ClassifierSizes,
    accuracy_from_probabilities,
    action_targets,
    derive_classes,
    load_action_classifier,
    read_labels,
    semantic_accuracy,
    train_action_classifier,
)

TINY = ClassifierSizes(hidden=32, blocks=3, kernel=5, dropout=0.0)


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    """40 procedural motions: 32 train, 2 val, 6 test."""
    out = tmp_path_factory.mktemp("synth") / "data"
    synthesize_dataset(out, num=40, seed=0, progress=False)
    return out


@pytest.fixture(scope="module")
def trained(data_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("classifier") / "cls"
    return train_action_classifier(data_dir, out, steps=150, batch_size=16, lr=1e-2, seed=0,
                                   progress=False, sizes=TINY)


def _features(data_dir, split):
    names = (data_dir / f"{split}.txt").read_text().split()
    return names, [np.load(data_dir / "new_joint_vecs" / f"{n}.npy") for n in names]


def test_targets_have_families_and_sides():
    record = {"name": "000001",
              "actions": [{"family": "kick", "params": {"leg": "left", "count": 2}},
                          {"family": "turn", "params": {"side": "right", "angle": 90}},
                          {"family": "bow", "params": {}}],
              "concurrent": None}
    assert action_targets(record) == {"kick", "kick:left", "turn", "turn:right", "bow"}
    walking = {"actions": [{"family": "walk", "params": {"speed": "slow", "direction": "forward"}}],
               "concurrent": {"family": "wave", "params": {"hand": "both", "count": 3}}}
    assert action_targets(walking) == {"walk", "wave", "wave:both"}
    assert derive_classes([record, walking]) == sorted(
        ["bow", "kick", "kick:left", "turn", "turn:right", "walk", "wave", "wave:both"])


def test_classes_of_a_benchmark(data_dir):
    labels = read_labels(data_dir)
    classes = derive_classes(labels.values())
    assert classes == sorted(classes) and len(labels) == 40
    families = {c for c in classes if ":" not in c}
    for c in classes:
        if ":" in c:
            family, side = c.split(":")
            assert family in families and side in ("left", "right", "both")


@pytest.mark.slow
def test_training_learns(trained, data_dir):
    losses = trained["losses"]
    assert len(losses) == 150 and np.mean(losses[-10:]) < 0.5 * np.mean(losses[:10])
    train = trained["accuracy"]["train"]
    # Chance: no class is in half the motions, so a constant answer detects nothing.
    assert train["mean_recall"] > 0.6 and train["exact_set_accuracy"] > 0.3
    assert trained["classes"] == trained["classifier"].classes


@pytest.mark.slow
def test_round_trip_and_batching(trained, data_dir):
    clf = trained["classifier"]
    loaded = load_action_classifier(trained["path"])
    assert loaded.classes == clf.classes and loaded.skeleton == "humanml3d"
    _, motions = _features(data_dir, "test")
    probs = clf.predict(motions)
    assert probs.shape == (len(motions), len(clf.classes))
    torch.testing.assert_close(loaded.predict(motions), probs, rtol=0, atol=0)
    # One at a time, or padded with garbage past each length: the same answers.
    alone = torch.cat([loaded.predict([m]) for m in motions])
    torch.testing.assert_close(alone, probs, rtol=1e-5, atol=1e-6)
    padded = torch.full((len(motions), 210, motions[0].shape[1]), 7.0)
    for i, m in enumerate(motions):
        padded[i, :len(m)] = torch.from_numpy(m)
    lengths = [len(m) for m in motions]
    torch.testing.assert_close(loaded.predict(padded, lengths), probs, rtol=1e-5, atol=1e-6)
    meta = json.loads((Path(trained["path"]) / "classifier.json").read_text())
    assert meta["feature_dim"] == 263 and meta["classes"] == clf.classes


def test_training_is_deterministic(data_dir, tmp_path):
    kwargs = dict(steps=3, batch_size=8, seed=1, progress=False, sizes=TINY)
    a = train_action_classifier(data_dir, tmp_path / "a", **kwargs)
    b = train_action_classifier(data_dir, tmp_path / "b", **kwargs)
    assert a["losses"] == b["losses"]


def test_accuracy_against_hand_computed_values():
    classes = ["kick", "kick:left", "kick:right", "walk"]
    probs = np.array([[0.9, 0.7, 0.2, 0.1],   # {kick, kick:left}: exact
                      [0.8, 0.6, 0.1, 0.0],   # {kick, kick:right}: side wrong
                      [0.1, 0.0, 0.0, 0.5],   # {walk}: exact (0.5 counts as detected)
                      [0.3, 0.0, 0.0, 0.9]])  # {kick, kick:left, walk}: kick missed
    targets = [{"kick", "kick:left"}, {"kick", "kick:right"}, {"walk"},
               {"kick", "kick:left", "walk"}]
    result = accuracy_from_probabilities(probs, classes, targets)
    assert result["recall"] == {"kick": 2 / 3, "kick:left": 1 / 2, "kick:right": 0.0,
                                "walk": 1.0}
    assert result["support"] == {"kick": 3, "kick:left": 2, "kick:right": 1, "walk": 2}
    assert result["precision"] == {"kick": 1.0, "kick:left": 1 / 2, "walk": 1.0}
    assert result["exact_set_accuracy"] == 2 / 4
    assert result["mean_recall"] == pytest.approx((2 / 3 + 1 / 2 + 0 + 1) / 4)
    with pytest.raises(MlctError, match="does not know: jump"):
        accuracy_from_probabilities(probs, classes, targets[:3] + [{"jump"}])


@pytest.mark.slow
def test_semantic_accuracy_matches_predictions(trained, data_dir):
    clf = trained["classifier"]
    names, motions = _features(data_dir, "test")
    labels = read_labels(data_dir)
    targets = [action_targets(labels[n]) for n in names]
    result = semantic_accuracy(clf, motions, targets)
    assert result == trained["accuracy"]["test"]
    assert result == accuracy_from_probabilities(clf.predict(motions), clf.classes, targets)


@pytest.mark.slow
def test_bad_inputs(trained, data_dir, tmp_path):
    clf = load_action_classifier(trained["path"])
    with pytest.raises(MlctError, match="reads 263-d humanml3d features; the motions are 251-d"):
        clf.predict([np.zeros((60, 251), dtype=np.float32)])
    with pytest.raises(MlctError, match="the motions are 263-d kit"):
        clf.check(263, "kit")
    plain = tmp_path / "plain"
    shutil.copytree(data_dir, plain)
    (plain / "labels.jsonl").unlink()
    with pytest.raises(MlctError, match="only procedural benchmarks"):
        train_action_classifier(plain, tmp_path / "out", steps=1, progress=False)
    with pytest.raises(MlctError, match="not an action classifier"):
        load_action_classifier(tmp_path)


def test_cli_trains_a_classifier_and_rejects_unlabelled_data(data_dir, tmp_path, capsys):
    from mlct.cli import main

    out = tmp_path / "cls"
    assert main(["train", "classifier", "--data", str(data_dir), "--out", str(out),
                 "--steps", "3", "--quiet"]) == 0
    assert "test exact-set accuracy" in capsys.readouterr().out
    assert load_action_classifier(out).classes
    plain = tmp_path / "plain"
    shutil.copytree(data_dir, plain)
    (plain / "labels.jsonl").unlink()
    assert main(["train", "classifier", "--data", str(plain), "--out", str(tmp_path / "x"),
                 "--quiet"]) == 2
    assert "only procedural benchmarks" in capsys.readouterr().err
