"""generate/compose/durations.py: the parts of a split prompt share the clip by how long each action takes."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import mlct
from mlct.errors import MlctError
from mlct.generate.compose.durations import (FILE, DurationModel, place_names, read_durations, split_frames,
                                    squeeze_longest_first)
from mlct.generate.bundle import bundled_model_dir
from mlct.train.durations import (SequenceExample, cut_errors, fit_durations, fit_offsets,
                                  sequence_examples, single_action_captions)


def _synthetic(n=600, dim=16, seed=0):
    """Durations that depend on the text vector through a product of two directions, which a
    linear map cannot fit (its r2 stays under 0.5 here)."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, dim))
    log_seconds = 1.0 + 0.3 * np.tanh(x[:, 0]) + 0.3 * np.tanh(x[:, 1] * x[:, 2])
    return x, np.exp(log_seconds + rng.normal(scale=0.01, size=n))


def test_the_network_fits_a_duration_a_linear_map_cannot():
    x, seconds = _synthetic()
    model = fit_durations(x, seconds, "enc", groups=np.arange(len(x)) // 2, steps=3000)
    assert model.fit["held_out_r2"] > 0.8
    assert model.fit["held_out_median_error"] < 0.08
    assert model.fit["motions"] == 300 and model.fit["examples"] == 600
    fresh, fresh_seconds = _synthetic(seed=1)
    error = np.abs(np.log(model.seconds(fresh)) - np.log(fresh_seconds))
    assert np.median(error) < 0.06
    z = np.c_[x, np.ones(len(x))]  # the linear map's best, for contrast
    coef = np.linalg.lstsq(z, np.log(seconds), rcond=None)[0]
    linear = np.abs(np.c_[fresh, np.ones(len(fresh))] @ coef - np.log(fresh_seconds))
    assert np.median(linear) > 2 * np.median(error)


def test_the_model_survives_its_file_and_reads_version_1(tmp_path):
    x, seconds = _synthetic(n=100)
    model = fit_durations(x, seconds, "enc", steps=200)
    model = DurationModel(model.weight, model.bias, "enc", model.fit, model.hidden_weight,
                          model.hidden_bias, {"first": 0.1, "middle": -0.4, "last": 0.2})
    model.save(tmp_path)
    data = json.loads((tmp_path / FILE).read_text())
    assert data["version"] == 2
    back = DurationModel.from_json(data, "here")
    np.testing.assert_allclose(back.seconds(x), model.seconds(x), rtol=1e-5)
    assert back.offsets == model.offsets
    one = {"format": "mlct-durations", "version": 1, "text_encoder": "enc", "bias": 0.5,
           "weight": [0.0] * 16}
    old = DurationModel.from_json(one, "old")
    # version 1 shares the clip in proportion to the seconds, as it always did
    np.testing.assert_allclose(old.part_weights(x[:3], 9.0, 1.0), np.exp(0.5))
    bad = dict(data, hidden_bias=data["hidden_bias"][:-1])
    with pytest.raises(MlctError, match="not a duration model"):
        DurationModel.from_json(bad, "bad")


def test_part_weights_give_each_part_its_duration_plus_its_place_offset():
    model = DurationModel(np.array([1.0]), 0.0, "enc", {},
                          offsets={"first": 0.2, "middle": -0.4, "last": 0.1})
    assert place_names(3) == ["first", "middle", "last"] and place_names(2) == ["first", "last"]
    parts = np.log([[3.0], [2.4], [2.0]])  # 3 s, 2.4 s, 2 s
    wanted = np.array([3.2, 2.0, 2.1])  # plus the offsets: 7.3 s in all
    share = split_frames(model.part_weights(parts, 7.3, 1.0), 146, 20)  # 7.3 s at 20 fps
    assert share == [64, 40, 42]
    np.testing.assert_allclose(np.array(share) / 20, wanted, atol=0.05)
    # a clip twice as long stretches every part alike
    share = split_frames(model.part_weights(parts, 14.6, 1.0), 292, 20)
    np.testing.assert_allclose(np.array(share) / 20, 2 * wanted, atol=0.05)


def test_a_clip_squeezed_past_the_datas_tempi_is_cut_from_the_longest_part_first():
    model = DurationModel(np.array([1.0]), 0.0, "enc", {}, offsets={"first": 0.0, "last": 0.0})
    parts = np.log([[4.6], [2.7]])  # a walk's 4.6 s, then a wave's 2.7 s: 7.3 s in all
    # 6.5 s is within the data's tempi (at least 7.3 / 1.15 = 6.35 s): squeezed alike
    share = split_frames(model.part_weights(parts, 6.5, 1.0), 130, 20)
    np.testing.assert_allclose(np.array(share) / 20, [4.6 * 6.5 / 7.3, 2.7 * 6.5 / 7.3], atol=0.05)
    # 5 s is not: both go to 1/1.15 of their time (4.0 s, 2.35 s), then the walk alone gives
    # up the rest; squeezed alike the wave would have had 1.85 s
    share = split_frames(model.part_weights(parts, 5.0, 1.0), 100, 20)
    np.testing.assert_allclose(np.array(share) / 20, [5 - 2.7 / 1.15, 2.7 / 1.15], atol=0.05)
    # the rule itself: the longer parts cut to a common length, the shortest kept
    np.testing.assert_allclose(squeeze_longest_first(np.array([3.0, 1.0, 4.0]), 5.0),
                               [2.0, 1.0, 2.0])
    # shorter than equal shares of the shortest: equal shares
    np.testing.assert_allclose(squeeze_longest_first(np.array([3.0, 2.0]), 1.0), [0.5, 0.5])
    # not shorter: every part alike, as a longer clip
    np.testing.assert_allclose(squeeze_longest_first(np.array([3.0, 1.0]), 4.0), [3.0, 1.0])


def test_the_offsets_and_cut_errors_come_from_the_sequences():
    model = DurationModel(np.array([1.0]), 0.0, "enc", {})
    vectors = {"a": [np.log(3.0)], "b": [np.log(2.0)], "c": [np.log(4.0)]}

    def embed(texts):
        return np.array([vectors[t] for t in texts])

    # the data: 0.2 s before the first action, 0.4 s overlaps, 0.3 s after the last
    examples = [SequenceExample(["a", "b", "c"], np.array([3.0, 2.0, 4.0]),
                                np.array([0.2 + 3.0 - 0.2, 0.2 + 3.0 - 0.4 + 2.0 - 0.2]),
                                0.2 + 3.0 + 2.0 + 4.0 - 0.8 + 0.3, 0)]
    fitted = fit_offsets(model, examples, embed, shift=0.0)
    assert fitted.offsets == pytest.approx({"first": 0.0, "middle": -0.4, "last": 0.1})
    assert np.abs(cut_errors(fitted, examples, embed, 20, 1.0, shift=0.0)).max() < 0.06
    assert np.abs(cut_errors(model, examples, embed, 20, 1.0, shift=0.0)).max() > 0.2
    # every cut earlier by the shift: the first part shorter, the last longer by it
    early = fit_offsets(model, examples, embed, shift=0.2)
    assert early.offsets == pytest.approx({"first": -0.2, "middle": -0.4, "last": 0.3})
    np.testing.assert_allclose(cut_errors(early, examples, embed, 20, 1.0, shift=0.0), -0.2,
                               atol=0.06)
    assert np.abs(cut_errors(early, examples, embed, 20, 1.0, shift=0.2)).max() < 0.06


def test_sequence_examples_take_the_captions_that_split_into_the_label():
    labels = {
        "s": {"actions": [{"family": "walk", "start": 0.2, "end": 3.0},
                          {"family": "bow", "start": 2.6, "end": 5.0}], "concurrent": None,
              "seconds": 5.2, "captions": ["walk, then bow", "walk and bow at once"]},
        "one": {"actions": [{"family": "jump", "start": 0.5, "end": 2.5}], "seconds": 3.0,
                "captions": ["jump"]},
    }

    def split(caption):
        return caption.split(", then ") if ", then " in caption else [caption]

    (example,) = sequence_examples(labels, split)
    assert example.parts == ["walk", "bow"] and example.total == 5.2
    np.testing.assert_allclose(example.seconds, [2.8, 2.4])
    np.testing.assert_allclose(example.cuts, [2.8])


def test_too_few_captions_is_a_clear_error():
    with pytest.raises(MlctError, match="need 10 or more captions"):
        fit_durations(np.zeros((3, 4)), np.ones(3), "enc")


def test_split_frames_are_proportional_sum_up_and_keep_a_minimum():
    model = DurationModel(np.array([1.0, 0.0]), 0.0, "enc", {})  # version 1: proportional
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


def test_auto_seconds_come_from_the_text():
    pipe = mlct.load(backend="torch")
    durations = pipe.durations
    assert durations is not None and durations.offsets  # the bundled model's version 2
    texts = ["a person jumps", "a person walks in a circle",
             "a person walks forward, then turns left",
             "a person walks forward while waving the left hand"]
    auto = pipe.auto_seconds(texts)
    jump, circle = durations.seconds(pipe.encode_text(texts[:2]).numpy())
    assert auto[0] == pytest.approx(jump + durations.single_extra)
    assert auto[1] == pytest.approx(circle + durations.single_extra)
    assert auto[1] > 2 * auto[0]  # a circle at walking pace is far longer than a jump
    parts = pipe.encode_text(["a person walks forward", "a person turns left"]).numpy()
    assert auto[2] == pytest.approx(float(durations.part_seconds(parts).sum()))
    # an arm action during another lasts as long as the other
    assert auto[3] == pytest.approx(pipe.auto_seconds(["a person walks forward"])[0])
    out = pipe.generate(texts[:2], seconds="auto", seed=0)
    assert [m.joints.shape[0] for m in out] == [pipe.frames_for(s) for s in auto[:2]]
    mixed = pipe.generate(texts[:2], seconds=["auto", 3.0], seed=0)
    assert [m.joints.shape[0] for m in mixed] == [pipe.frames_for(auto[0]), 60]
    np.testing.assert_allclose(mixed[0].joints, out[0].joints, atol=1e-5)
    with pytest.raises(MlctError, match='seconds must be a number, a list of them or "auto"'):
        pipe.generate("a person jumps", seconds="soon")


def test_a_far_prompt_is_timed_as_the_text_anchors_pull_it():
    """The duration model reads the vector the network samples from: a wording unlike every
    caption, pulled towards the circle walks, gets a circle walk's length, not the 5 s floor
    that cut its circle off at ~250 degrees when the raw vector was read."""
    pipe = mlct.load(backend="torch")
    text = "walk around in a circle going anticlockwise"
    raw = pipe.encode_text([text])
    pulled = pipe.sampling_text(raw)
    assert pipe.text_anchors.weights(raw)[0][0].item() > 0.5  # far: the anchors move it
    durations = pipe.durations
    as_pulled = durations.clip_seconds(pulled.numpy())
    assert as_pulled - durations.clip_seconds(raw.numpy()) > 1.0
    assert pipe.auto_seconds([text])[0] == pytest.approx(as_pulled)
    assert as_pulled > 6.0 and pipe.default_seconds([text])[0] == pytest.approx(as_pulled)
    near = "a person walks in a circle"  # a caption's wording: not moved, timed as before
    assert pipe.auto_seconds([near])[0] == pytest.approx(
        durations.clip_seconds(pipe.encode_text([near]).numpy()))


def test_auto_seconds_need_a_duration_model(tmp_path):
    folder = tmp_path / "m"
    shutil.copytree(bundled_model_dir(), folder)
    bare = pipe_without(folder)
    with pytest.raises(MlctError, match="no duration model.*mlct train durations"):
        bare.generate("a person jumps", seconds="auto")


def test_the_cli_takes_seconds_auto(tmp_path, capsys):
    from mlct.cli import main

    out = tmp_path / "jump.npy"
    assert main(["generate", "a person jumps", "--seconds", "auto", "--seed", "0",
                 "--out", str(out), "--quiet"]) == 0
    pipe = mlct.load(backend="torch")
    assert np.load(out).shape[0] == pipe.frames_for(pipe.auto_seconds(["a person jumps"])[0])
    long = tmp_path / "long.npy"
    prompts = ["a person walks forward", "a person turns left", "a person squats"]
    assert main(["generate", *prompts, "--seconds", "auto", "--seed", "0", "--out", str(long),
                 "--quiet"]) == 0
    natural = pipe.durations.part_seconds(pipe.encode_text(prompts).numpy())
    # the segments overlap by their blends, so the motion is the sum of the shares
    expected = sum(pipe.frames_for(max(s, 1.0)) for s in natural)
    assert np.load(long).shape[0] == expected
    capsys.readouterr()
    with pytest.raises(SystemExit) as error:
        main(["generate", "a person jumps", "--seconds", "soon", "--out", str(out)])
    assert error.value.code == 2
    assert "not a number of seconds or 'auto'" in capsys.readouterr().err
