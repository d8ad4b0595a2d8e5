"""generate/durations.py: the parts of a split prompt share the clip by how long each action takes."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import mlct
from mlct.errors import MlctError
from mlct.generate.durations import (FILE, DurationModel, fit_durations, split_frames,
                                     read_durations, single_action_captions)
from mlct.generate.pipeline import bundled_model_dir


def _synthetic(n=400, dim=16, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, dim))
    true_w = rng.normal(scale=0.2, size=dim)
    seconds = np.exp(x @ true_w + 1.0 + rng.normal(scale=0.01, size=n))
    return x, seconds, true_w


def test_the_fit_recovers_a_log_linear_duration():
    x, seconds, true_w = _synthetic()
    model = fit_durations(x, seconds, "enc", groups=np.arange(len(x)) // 2)
    assert model.fit["held_out_r2"] > 0.98
    assert model.fit["motions"] == 200 and model.fit["captions"] == 400
    np.testing.assert_allclose(model.weight, true_w, atol=0.01)
    assert abs(model.bias - 1.0) < 0.01
    np.testing.assert_allclose(model.seconds(x[:5]), seconds[:5], rtol=0.03)


def test_too_few_captions_is_a_clear_error():
    with pytest.raises(MlctError, match="need 10 or more captions"):
        fit_durations(np.zeros((3, 4)), np.ones(3), "enc")


def test_split_frames_are_proportional_sum_up_and_keep_a_minimum():
    model = DurationModel(np.array([1.0, 0.0]), 0.0, "enc", {})
    parts = np.array([[np.log(3.0), 0.0], [0.0, 5.0]])  # 3 s and 1 s
    assert split_frames(model.seconds(parts), 100, 20) == [65, 35]  # 20 each + 60 shared 3:1
    assert sum(split_frames(model.seconds(parts), 101, 20)) == 101
    # a part predicted far shorter still gets the minimum
    tiny = np.array([[np.log(100.0), 0.0], [0.0, 0.0]])
    assert split_frames(model.seconds(tiny), 100, 20)[1] >= 20
    # no model: equal shares, the rounding to one part
    assert split_frames(np.ones(3), 100, 20) == [34, 33, 33]
    # a total below the minimum: what there is, equally
    assert split_frames(np.ones(2), 30, 20) == [15, 15]


def test_single_action_captions_take_one_action_motions_only():
    labels = {
        "a": {"actions": [{"family": "jump", "start": 0.5, "end": 2.5}], "concurrent": None,
              "captions": ["a person jumps", "someone hops up"]},
        "b": {"actions": [{"family": "walk", "start": 0, "end": 2},
                          {"family": "bow", "start": 1.6, "end": 3}], "captions": ["x"]},
        "c": {"actions": [{"family": "walk", "start": 0, "end": 4}],
              "concurrent": {"family": "wave"}, "captions": ["y"]},
    }
    texts, seconds, groups = single_action_captions(labels)
    assert texts == ["a person jumps", "someone hops up"]
    assert seconds.tolist() == [2.0, 2.0] and groups.tolist() == [0, 0]
    with pytest.raises(MlctError, match="no labelled single-action motions"):
        single_action_captions({"b": labels["b"]})


def test_a_model_folder_reads_its_durations_and_refuses_a_foreign_one(tmp_path):
    folder = tmp_path / "m"
    shutil.copytree(bundled_model_dir(), folder)
    (folder / FILE).unlink(missing_ok=True)
    meta = json.loads((folder / "config.json").read_text())
    assert read_durations(folder, meta["text_encoder"], meta["text_dim"]) is None
    dim = meta["text_dim"]
    model = DurationModel(np.zeros(dim), np.log(2.0), meta["text_encoder"], {"captions": 1})
    model.save(folder)
    got = read_durations(folder, meta["text_encoder"], dim)
    assert got is not None and got.seconds(np.ones((1, dim)))[0] == pytest.approx(2.0)
    with pytest.raises(MlctError, match="refit it with `mlct train durations`"):
        read_durations(folder, "minilm", dim)
    (folder / FILE).write_text('{"format": "mlct-durations", "version": 1, "weight": "x"}')
    with pytest.raises(MlctError, match="not a duration model"):
        mlct.load(folder, backend="torch")


def test_split_prompt_parts_share_the_clip_by_predicted_duration(tmp_path):
    folder = tmp_path / "m"
    shutil.copytree(bundled_model_dir(), folder)
    meta = json.loads((folder / "config.json").read_text())
    pipe = mlct.load(folder, backend="torch")
    walk, turn = "a person walks forward", "a person turns left"
    # a duration model that makes the walk three times as long as the turn
    e_walk, e_turn = pipe.encode_text([walk, turn]).float().numpy().astype(np.float64)
    direction = (e_walk - e_turn) / np.dot(e_walk - e_turn, e_walk - e_turn)
    bias = -float(np.dot(direction, e_turn))  # log seconds: 0 for the turn, log 3 for the walk
    DurationModel(direction * np.log(3.0), bias, meta["text_encoder"], {}).save(folder)
    timed = mlct.load(folder, backend="torch")
    out = timed.generate(f"{walk}, then turns left", seconds=8, seed=0)[0]
    assert out.texts == (walk, turn)
    # 160 frames: 20 each as the minimum, the other 120 shared 3:1
    assert out.seams == (110,)
    equal = pipe_without(folder).generate(f"{walk}, then turns left", seconds=8, seed=0)[0]
    assert equal.seams == (80,)


def pipe_without(folder):
    (folder / FILE).unlink()
    return mlct.load(folder, backend="torch")
