"""Prompts, the generation result, long motions and `mlct generate` with the bundled model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import mlct
from mlct.cli import main
from mlct.errors import MlctError
from mlct.generate.files import output_paths, slug
from mlct.generate.compose.long_motion import chain_segments, generate_long, seam_speeds
from mlct.generate.control.facing import heading
from mlct.motion.skeleton import get_skeleton
from mlct.generate.compose.prompts import MAX_PROMPT_CHARS, clean_prompt, read_prompts, stated_seconds

pytestmark = pytest.mark.usefixtures("one_thread")
SKELETON = get_skeleton("humanml3d")


@pytest.fixture(scope="module")
def bundled():
    return mlct.load()


def test_clean_prompt_collapses_whitespace_and_rejects_bad_text() -> None:
    assert clean_prompt("  a person\t walks\nforward ") == "a person walks forward"
    assert clean_prompt("une personne saute") == "une personne saute"  # not only ASCII
    for bad, message in [("", "empty"), (" \t\n", "empty"), ("a" * 10_000, "10000 characters"),
                         ("walk\x07", r"U\+0007"), ("walk\x00", r"U\+0000"), ("a\u202eb", r"U\+202E"),
                         (3, "must be a string")]:
        with pytest.raises(MlctError, match=message):
            clean_prompt(bad)
    assert len(clean_prompt("a" * MAX_PROMPT_CHARS)) == MAX_PROMPT_CHARS


def test_read_prompts(tmp_path: Path) -> None:
    good = tmp_path / "p.txt"
    good.write_text("a person runs\n\n# a comment\n  a person squats  \n", encoding="utf-8")
    assert read_prompts(good) == ["a person runs", "a person squats"]
    bad = tmp_path / "bad.txt"
    bad.write_bytes(b"a person runs\n\xff\xfe walks\n")
    with pytest.raises(MlctError, match="line 2 is not valid UTF-8"):
        read_prompts(bad)
    empty = tmp_path / "empty.txt"
    empty.write_text("\n# nothing\n", encoding="utf-8")
    with pytest.raises(MlctError, match="no prompts"):
        read_prompts(empty)


def test_output_paths(tmp_path: Path) -> None:
    assert slug("A person walks forward, then waves!") == "a_person_walks_forward_then_waves"
    assert output_paths(["x"], tmp_path / "a.bvh", None, None) == [tmp_path / "a.bvh"]
    assert output_paths(["x", "y"], tmp_path / "a.gif", None, None) == [
        tmp_path / "a_000.gif", tmp_path / "a_001.gif"]
    assert output_paths(["run", "jump"], None, tmp_path / "d", "npy") == [
        tmp_path / "d" / "000_run.npy", tmp_path / "d" / "001_jump.npy"]
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for args, message in [((tmp_path / "a.txt", None, None), "cannot tell the format"),
                          ((None, tmp_path, "doc"), "cannot tell the format"),
                          ((blocker / "a.gif", None, None), "not a directory"),
                          ((None, None, None), "give --out"),
                          ((tmp_path / "a.gif", None, "gif"), "--format goes with --out-dir")]:
        with pytest.raises(MlctError, match=message):
            output_paths(["x"], *args)


def _walk(frames: int, speed: float, turn_rate: float = 0.0) -> np.ndarray:
    """A rigid rest pose gliding forward along its heading, turning at turn_rate rad/frame."""
    pose = np.zeros((SKELETON.n_joints, 3))
    for j, parent in enumerate(SKELETON.parents):
        pose[j] = (pose[parent] if parent >= 0 else np.array([0, 0.9, 0])) \
            + SKELETON.rest_offsets[j]
    out, position, angle = [], np.zeros(3), 0.0
    for _ in range(frames):
        c, s = np.cos(angle), np.sin(angle)
        turned = pose @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
        out.append(turned + position)
        position = position + speed * np.array([s, 0.0, c])
        angle += turn_rate
    return np.stack(out)


def test_heading_is_zero_facing_z_and_follows_a_turn() -> None:
    walk = _walk(30, 0.05, turn_rate=0.02)
    assert abs(heading(walk[0], SKELETON)) < 1e-3  # the rest pose is nearly symmetric
    turned = np.unwrap(heading(walk, SKELETON)) - heading(walk[0], SKELETON)
    assert np.allclose(turned, 0.02 * np.arange(30), atol=1e-6)


def test_chaining_a_split_motion_gives_it_back() -> None:
    walk = _walk(90, 0.06, turn_rate=0.015)
    joined, seams = chain_segments([walk[:50], walk[40:]], blend=10, skeleton=SKELETON)
    assert seams == [40] and joined.shape == walk.shape
    assert np.abs(joined - walk).max() < 1e-4  # 0.1 mm: frame 0 of a segment has no velocity of its own


def test_chaining_carries_position_and_heading_on() -> None:
    # the second segment starts at the origin facing +Z, like every generated one
    first, second = _walk(60, 0.05, turn_rate=0.02), _walk(40, 0.05)
    joined, _ = chain_segments([first, second], blend=10, skeleton=SKELETON)
    root_speed = np.linalg.norm(np.diff(joined[:, 0], axis=0), axis=-1)
    # no jump back to the origin at the seam (blending two velocity directions shortens it a bit)
    assert np.allclose(root_speed, 0.05, atol=1e-4)
    # the turn eases out over the blend (sum of 1 - smoothstep = 5 frames at 0.02), then stops
    after = np.unwrap(heading(joined[59:], SKELETON))
    assert np.allclose(after, heading(first[49], SKELETON) + 5 * 0.02, atol=1e-6)


def test_long_motion_with_the_bundled_model(bundled) -> None:
    motion = generate_long(bundled, ["a person walks forward", "a person turns left",
                                     "a person waves with the right hand"], [3, 2, 2], nfe=3,
                           seed=0)
    assert motion.joints.shape == (140, 22, 3) and np.isfinite(motion.joints).all()
    assert motion.features.shape == (140, 263)  # one row per frame, as the joints
    assert len(motion.seams) == 2 and len(motion.segments) == 3
    speeds = seam_speeds(motion)
    assert speeds["seam_max"] <= speeds["segments_max"]
    with pytest.raises(MlctError, match="one each"):
        generate_long(bundled, ["a", "b"], [3], nfe=1)
    # past the window only a gait keeps going (generate/compose/keep_going.py)
    with pytest.raises(MlctError, match="'a person jumps': .* only a gait"):
        generate_long(bundled, ["a person jumps", "b"], [9.8, 3], nfe=1)
    bundled.keep_going = False
    try:
        with pytest.raises(MlctError, match="at most"):
            generate_long(bundled, ["a", "b"], [9.8, 3], nfe=1)
    finally:
        bundled.keep_going = True


def test_generation_saves_every_format(bundled, tmp_path: Path) -> None:
    out = bundled.generate(["a person runs", "a person squats"], seconds=[2, 1.5], nfe=2, seed=3)
    paths = out.save(tmp_path / "m.json")
    assert [p.name for p in paths] == ["m_000.json", "m_001.json"]
    record = json.loads(paths[1].read_text())
    assert record["text"] == "a person squats" and record["seed"] == 4 and record["fps"] == 20
    assert np.allclose(record["joints"], out[1].joints, atol=1e-4)
    assert record["parents"] == list(SKELETON.parents)
    out[0].save(tmp_path / "f.npy", features=True)
    assert np.load(tmp_path / "f.npy").shape == (40, 263)
    with pytest.raises(MlctError, match="only be saved as .npy"):
        out[0].save(tmp_path / "f.json", features=True)


def test_cli_generate_variations_prompts_file_and_long(tmp_path: Path, capsys) -> None:
    assert main(["generate", "a person walks forward", "--num", "2", "--seconds", "2", "--nfe",
                 "2", "--seed", "7", "--out", str(tmp_path / "w.npy"), "--quiet"]) == 0
    a, b = np.load(tmp_path / "w_000.npy"), np.load(tmp_path / "w_001.npy")
    assert a.shape == (40, 22, 3) and not np.allclose(a, b)
    # variation 1 of seed 7 is the motion of seed 8
    assert main(["generate", "a person walks forward", "--seconds", "2", "--nfe", "2", "--seed",
                 "8", "--out", str(tmp_path / "s8.npy")]) == 0
    assert np.allclose(np.load(tmp_path / "s8.npy"), b, atol=1e-5)  # batch of 1 vs 2: rounding
    prompts = tmp_path / "prompts.txt"
    prompts.write_text("a person runs\na person squats\n", encoding="utf-8")
    assert main(["generate", "--prompts", str(prompts), "--length", "30", "20", "--nfe", "1",
                 "--out-dir", str(tmp_path / "d"), "--format", "npy", "--quiet"]) == 0
    assert [np.load(p).shape[0] for p in sorted((tmp_path / "d").iterdir())] == [30, 20]
    # bfloat16 products: the same motion within a few millimetres (docs/performance.md)
    assert main(["generate", "a person walks forward", "--seconds", "2", "--nfe", "2", "--seed",
                 "8", "--dtype", "bfloat16", "--out", str(tmp_path / "bf16.npy")]) == 0
    assert np.abs(np.load(tmp_path / "bf16.npy") - b).mean() < 0.02
    assert main(["generate", "a person walks forward", "a person jumps", "--seconds", "2", "2",
                 "--nfe", "1", "--seed", "0", "--out", str(tmp_path / "long.npy")]) == 0
    assert np.load(tmp_path / "long.npy").shape == (80, 22, 3)
    capsys.readouterr()
    for argv, message in [
            (["generate", "run", "--prompts", str(prompts), "--out-dir", str(tmp_path)],
             "not both"),
            (["generate", "a", "b", "--num", "2", "--seconds", "2", "2", "--out", "x.gif"],
             "--num makes variations"),
            (["generate", "a", "b", "--out", str(tmp_path / "l.gif")], "one duration a prompt"),
            (["generate", "run", "--seconds", "-1", "--out", str(tmp_path / "x.gif")],
             "positive"),
            (["generate", "run", "--num", "0", "--out", str(tmp_path / "x.gif")], "at least 1")]:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert message in err and err.count("\n") == 0, err


def test_damaged_model_directories_give_one_line_errors(tmp_path: Path, capsys) -> None:
    import shutil

    from mlct.generate.bundle import bundled_model_dir

    model = tmp_path / "model"
    shutil.copytree(bundled_model_dir(), model)
    weights = (model / "model.safetensors").read_bytes()
    config = (model / "config.json").read_text()
    damages = [
        (lambda: (model / "model.safetensors").write_bytes(weights[:5000]), "unreadable weights"),
        (lambda: (model / "config.json").write_text("{bad json"), "unreadable"),
        (lambda: (model / "config.json").write_text('{"format": "mlct-model", "version": 1}'),
         "incomplete model config"),
        (lambda: (model / "config.json").unlink(), "not an mlct model"),
    ]
    for damage, message in damages:
        (model / "model.safetensors").write_bytes(weights)
        (model / "config.json").write_text(config)
        damage()
        capsys.readouterr()
        assert main(["generate", "walk", "--model", str(model), "--out",
                     str(tmp_path / "x.npy")]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and err.count("\n") == 0, err
    assert not (tmp_path / "x.npy").exists()


@pytest.mark.parametrize("text, clean, seconds", [
    ("a person walks forward for 20 seconds", "a person walks forward", 20.0),
    ("a person jogs for half a minute", "a person jogs", 30.0),
    ("a man waves for 3 s, smiling", "a man waves, smiling", 3.0),
    ("someone runs for about 12.5 secs", "someone runs", 12.5),
    ("a person stands still for a second", "a person stands still", 1.0),
    ("a person walks forward for 2 minutes", "a person walks forward", 120.0),
    ("a person waits for his friend", "a person waits for his friend", None),  # not a duration
    ("a person walks for 5 seconds, then waves for 3 seconds",  # two: the parts' own
     "a person walks for 5 seconds, then waves for 3 seconds", None),
    ("for 10 seconds", "for 10 seconds", None),  # nothing left to do
])
def test_a_prompt_may_say_how_long(text, clean, seconds) -> None:
    assert stated_seconds(text) == (clean, seconds)


def test_the_stated_length_sets_the_clip_unless_the_caller_gives_one(bundled) -> None:
    fps = bundled.skeleton.fps
    said = bundled.generate("a person walks forward for 12 seconds", seed=0)[0]
    assert said.joints.shape[0] == int(12 * fps)
    assert said.text == "a person walks forward for 12 seconds"  # kept as written
    plain = bundled.generate("a person walks forward", seconds=12, seed=0)[0]
    np.testing.assert_allclose(said.joints, plain.joints, atol=1e-5)  # the model read the same
    assert bundled.generate("a person jumps for 2 seconds", seconds=3,
                            seed=0)[0].joints.shape[0] == int(3 * fps)
    # in a sequence the phrase stays: whose duration it is is not clear
    text = "a person walks for 3 seconds, then waves"  # the default length, not 3 s
    default = bundled.frames_for(bundled.default_seconds([text])[0])
    assert bundled.generate(text, seed=0)[0].joints.shape[0] == default != int(3 * fps)


def test_the_default_length_is_five_seconds_or_what_the_actions_take(bundled) -> None:
    fps = bundled.skeleton.fps
    circle, kick = "a person walks in a circle", "a person kicks"
    natural = bundled.auto_seconds([circle, kick])
    assert natural[0] > 6.0 and natural[1] < 5.0  # a circle takes longer, a kick less
    assert bundled.default_seconds([circle, kick]) == [natural[0], 5.0]
    made = bundled.generate([circle, kick], seed=0)
    assert list(made.lengths) == [bundled.frames_for(natural[0]), int(5 * fps)]
    # a caller's seconds still win, and a model without a duration model keeps 5 s
    assert bundled.generate(circle, seconds=4, seed=0)[0].joints.shape[0] == int(4 * fps)
    durations, bundled.durations = bundled.durations, None
    try:
        assert bundled.default_seconds([circle]) == [5.0]
    finally:
        bundled.durations = durations


def test_in_place_keeps_the_pelvis_over_its_start(bundled, tmp_path) -> None:
    walk = bundled.generate("a person walks forward", seconds=4, seed=0)[0]
    still = walk.in_place()
    pelvis = still.joints[:, 0]
    np.testing.assert_allclose(pelvis[:, [0, 2]], np.repeat(pelvis[:1, [0, 2]], 80, 0),
                               atol=1e-6)
    np.testing.assert_allclose(pelvis[:, 1], walk.joints[:, 0, 1])  # the height as it was
    # every pose is the same relative to the pelvis; the original is untouched
    np.testing.assert_allclose(still.joints - still.joints[:, :1],
                               walk.joints - walk.joints[:, :1], atol=1e-6)
    assert np.linalg.norm(walk.joints[-1, 0, [0, 2]] - walk.joints[0, 0, [0, 2]]) > 1.0
    assert still.features.shape == walk.features.shape
    from mlct.cli import main

    out = tmp_path / "w.npy"
    assert main(["generate", "a person walks forward", "--seconds", "4", "--seed", "0",
                 "--backend", "torch", "--in-place", "--out", str(out)]) == 0
    np.testing.assert_allclose(np.load(out), still.joints, atol=1e-5)
