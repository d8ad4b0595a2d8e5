"""Controls (generate/control/schema.py, control/fit.py, control/controlled.py): the schema and its errors,
and each control met on a motion the bundled model generates."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import mlct
from mlct.cli import main
from mlct.errors import MlctError
from mlct.generate.control.schema import Control, Keyframe, control_from_dict, part_joints
from mlct.generate.control.files import read_path_file
from mlct.generate.control.fit import fabrik, offset_curve
from mlct.generate.control.controlled import ControlMethod, generate_controlled
from mlct.motion.skeleton import get_skeleton

pytestmark = pytest.mark.usefixtures("one_thread")
SKELETON = get_skeleton("humanml3d")
WRIST = SKELETON.index("right_wrist")
PATH = [[0.0, 0.0, 0], [0.2, 1.2, 40], [0.9, 2.2, 80], [1.9, 2.6, 119]]


def bone_lengths(joints: np.ndarray) -> np.ndarray:
    """(T, J): each joint's distance to its parent (0 for the root)."""
    parents = [max(p, 0) for p in SKELETON.parents]
    return np.linalg.norm(joints - joints[:, parents], axis=-1)


@pytest.fixture(scope="module")
def pipe():
    return mlct.load()


@pytest.fixture(scope="module")
def walk(pipe):
    return pipe.generate("a person walks forward", lengths=120, seed=3)[0].joints


# ---------------------------------------------------------------- schema, no model


def test_schema_reads_every_form_of_waypoint_and_keyframe(tmp_path: Path) -> None:
    control = control_from_dict({"path": [[0, 0], {"x": 1, "z": 2, "heading": 90}, [3, 4]]},
                                SKELETON).check(100, SKELETON)
    assert control.path.shape == (3, 2) and control.path_frames.tolist()[::2] == [0, 99]
    assert np.isnan(control.heading[0]) and control.heading[1] == pytest.approx(np.pi / 2)
    csv = tmp_path / "p.csv"
    csv.write_text("x,z,frame\n0,0,0\n0.5,1,30\n", encoding="utf-8")
    assert read_path_file(csv) == [{"x": 0.0, "z": 0.0, "frame": 0.0},
                                   {"x": 0.5, "z": 1.0, "frame": 30.0}]
    pose = np.zeros((22, 3)).tolist()
    keys = control_from_dict({"keyframes": [
        {"frame": 5, "pose": pose}, {"frame": 9, "joint": "left_wrist", "position": [1, 1, 0]},
        {"frame": 9, "joints": {"head": [0, 2, 0]}}], "start_pose": pose, "end_pose": pose},
        SKELETON, frames=50).keyframes
    assert [k.frame for k in keys] == [5, 9, 9, 0, 49] and len(keys[0].joints) == 22
    assert part_joints("left_arm", SKELETON) == (13, 16, 18, 20)
    assert set(part_joints("upper", SKELETON)) == set(range(22)) - {0, 1, 2, 4, 5, 7, 8, 10, 11}


@pytest.mark.parametrize("data, frames, message", [
    ({"path": [[0, 0, 0], [1, 1, 300]]}, 100, "frame 300 is outside 0..99"),
    ({"path": [[0, 0, 0], [1, 1]]}, 100, "every waypoint or for none"),
    ({"path": [[0, float("nan")]]}, 100, "NaN"),
    ({"path": [[0, 0, 1, 2]]}, 100, "path[0]"),
    ({"keyframes": [{"frame": 3, "joint": "left_pinky", "position": [0, 0, 0]}]}, 100,
     "unknown joint 'left_pinky'"),
    ({"keyframes": [{"frame": 3, "pose": [[0, 0, 0]] * 21}]}, 100, "22 [x, y, z] points"),
    ({"keyframes": [{"frame": -1, "joint": "head", "position": [0, 0, 0]}]}, 100, "outside"),
    ({"keyframes": [{"frame": 3, "joint": "head", "position": [0, 0]}]}, 100, "[x, y, z]"),
    ({"edit": np.zeros((50, 22, 3)).tolist(), "parts": "upper"}, 100, "keeps the motion's length"),
    ({"edit": np.zeros((100, 22, 3)).tolist()}, 100, "needs the parts"),
    ({"edit": np.zeros((100, 22, 3)).tolist(), "parts": "wings"}, 100, "unknown part 'wings'"),
    ({"edit": np.zeros((100, 21, 3)).tolist(), "parts": "upper"}, 100, "shape"),
    ({"prefix": np.zeros((100, 22, 3)).tolist()}, 100, "ask for more frames"),
    ({"spline": []}, 100, "unknown control field 'spline'"),
])
def test_bad_controls_raise_one_line_errors(data, frames, message) -> None:
    with pytest.raises(MlctError) as error:
        control_from_dict(data, SKELETON).check(frames, SKELETON)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_offset_curve_passes_its_knots_and_eases_out() -> None:
    curve = offset_curve(np.array([20, 60]), np.array([[1.0], [-2.0]]), 100, reach=15)
    assert curve[20, 0] == pytest.approx(1.0) and curve[60, 0] == pytest.approx(-2.0)
    assert curve[:6].max() == 0 and curve[76:].min() == 0 and curve[40, 0] == 0
    step = np.abs(np.diff(curve[:, 0]))
    assert step[4:7].max() < 0.06 and step.max() < 0.3  # eases in: no kink, no jump


def test_fabrik_reaches_and_keeps_bone_lengths() -> None:
    chain = np.array([[0, 0, 0], [0, -0.3, 0], [0, -0.6, 0.0]])
    out = fabrik(chain, np.array([0.3, -0.3, 0.2]), np.array([0.3, 0.3]))
    assert np.linalg.norm(out[-1] - [0.3, -0.3, 0.2]) < 1e-4 and np.allclose(out[0], 0)
    assert np.allclose(np.linalg.norm(np.diff(out, axis=0), axis=1), 0.3)


# ---------------------------------------------------------------- controls met by the model


def test_path_is_met_and_guidance_brings_the_motion_near_it(pipe) -> None:
    # the sampled ways (candidates, guidance) on their own: the default walks a path by the
    # text's motion re-timed to it (control/pace.py, tests/test_control_pace.py)
    control = control_from_dict({"path": PATH}, SKELETON)
    frames = [p[2] for p in PATH]
    target = np.array(PATH)[:, :2]

    def error(method: ControlMethod, seed: int = 3) -> np.ndarray:
        made = generate_controlled(pipe, "a person walks forward", 120, control.check(120, SKELETON),
                                   None, seed, method).joints
        return np.linalg.norm(made[frames, 0][:, [0, 2]] - target, axis=1)

    plain = error(ControlMethod(pace=False, guide=False, project=False, candidates=1))
    # Guidance alone, over 6 seeds: the waypoint error as a share of plain sampling's was 0.61
    # with the noise-trained decoder, 0.77 with the trajectory-trained decoder under the stage 2
    # trained before it (seed 3: 1.07), 0.64 with the model trained on that decoder; with the
    # bundled model (decoder noise 0.2) 0.93 at 1 + 2 gradient steps, 0.46 at the 2 + 4 now
    # the default (the model before: 0.43). One seed's ratio ranges over 0.2-1.6, so the 6-seed
    # mean moves by ~0.15 between models that 30 seeds cannot tell apart
    # (bench/control.py --guidance): the soup of three colloquial seeds at 0.7 (2026-11-27,
    # evening) 0.69 here, 0.56 over 30; the same soup at 1, not shipped, 0.95 here, 0.68 over 30.
    # The one-pass recipe's model (2026-11-28, seed 0): 0.91 here (seeds: 0.45-1.58), so guidance
    # alone helps it less; guidance with projection, the default, still meets the path (below).
    # Version 7 (a 96-channel body decoder): 1.07 here at 2 + 4 steps (30 seeds: 1.01, version 6
    # 0.73), 0.53 at the 4 + 8 now the default (30 seeds: 0.55, version 6 0.55).
    guided = ControlMethod(pace=False, guide=True, project=False, candidates=1)
    unguided = ControlMethod(pace=False, guide=False, project=False, candidates=1)
    ratios = [error(guided, s).mean() / error(unguided, s).mean() for s in range(6)]
    assert np.mean(ratios) < 1.0, ratios
    best = error(ControlMethod(pace=False, guide=False, project=False, candidates=4))
    # the seed's own motion is one of the candidates, and the kept one has the least squared
    # error (control_loss's measure; the mean distance may order two candidates otherwise)
    assert (best ** 2).mean() <= (plain ** 2).mean() + 1e-9
    both = pipe.generate("a person walks forward", lengths=120, seed=3,
                         control={"path": PATH})[0].joints
    assert np.linalg.norm(both[frames, 0][:, [0, 2]] - target, axis=1).max() < 0.01
    # still a walk: the feet take turns and the body keeps its bones
    assert np.ptp(both[:, 10, 1]) > 0.05 and np.ptp(both[:, 11, 1]) > 0.05
    assert np.abs(np.diff(both, axis=0)).max() < 0.25  # no jump between frames (m/frame)


def test_heading_turns_the_body_to_face_the_given_way(pipe) -> None:
    from mlct.generate.control.facing import heading

    path = [{"x": 0, "z": 0, "frame": 0, "heading": 90}, {"x": 2, "z": 0, "frame": 99}]
    made = pipe.generate("a person walks forward", lengths=100, seed=1,
                         control={"path": path})[0].joints
    assert abs(np.degrees(heading(made[0], SKELETON)) - 90) < 2  # starts facing +X
    assert made[-1, 0, 0] == pytest.approx(2.0, abs=0.01)


def test_keyframes_full_pose_and_end_effector(pipe, walk) -> None:
    target = walk[60] + np.array([0.3, 0.0, 0.2])  # the whole pose, moved
    wrist = walk[90, WRIST] + np.array([0.0, 0.35, 0.15])  # the right hand raised
    keys = (Keyframe(60, {j: tuple(p) for j, p in enumerate(target)}),
            Keyframe(90, {WRIST: tuple(wrist)}))
    made = pipe.generate("a person walks forward", lengths=120, seed=3,
                         control=Control(keyframes=keys))[0].joints
    assert np.linalg.norm(made[60] - target, axis=-1).max() < 0.01
    assert np.linalg.norm(made[90, WRIST] - wrist) < 0.01
    # FABRIK keeps the arm's bones: as long at the key frame as in the same motion uncorrected
    guided = generate_controlled(pipe, "a person walks forward", 120,
                                 Control(keyframes=keys).check(120, SKELETON), None, 3,
                                 ControlMethod(project=False)).joints
    arm = [SKELETON.index(n) for n in ("right_shoulder", "right_elbow", "right_wrist")]
    assert np.abs(bone_lengths(made)[90, arm] - bone_lengths(guided)[90, arm]).max() < 1e-3
    # between the keys each bone's length eases from the model's own to the key pose's and
    # never further (independent joint offsets alone stretched them by decimetres)
    gap = np.abs(bone_lengths(target[None])[0] - bone_lengths(guided)[60])  # (J,)
    assert (np.abs(bone_lengths(made) - bone_lengths(guided)).max(0) <= gap + 2e-3).all()


def test_upper_body_edit_keeps_every_other_joint(pipe, walk) -> None:
    parts = part_joints("upper", SKELETON)
    made = pipe.generate("a person waves with the right hand", seed=5,
                         control={"edit": walk.tolist(), "parts": "upper"})[0].joints
    kept = [j for j in range(22) if j not in parts]
    assert made.shape == walk.shape
    assert np.linalg.norm(made[:, kept] - walk[:, kept], axis=-1).max() < 0.01
    assert np.abs(made[:, list(parts)] - walk[:, list(parts)]).max() > 0.1  # the arms changed
    assert np.abs(bone_lengths(made) - bone_lengths(walk)).max() < 1e-3


def test_prefix_is_continued_and_between_poses_are_met(pipe, walk) -> None:
    seam_ratios = []
    for seed in range(6):
        made = pipe.generate("a person jumps", lengths=100, seed=seed,
                             control={"prefix": walk[:40].tolist()})[0].joints
        assert made.shape == (100, 22, 3)
        assert np.linalg.norm(made[:40] - walk[:40], axis=-1).max() < 0.01
        speed = np.linalg.norm(np.diff(made, axis=0), axis=-1).max(axis=1)  # (T-1,) m a frame
        seam_ratios.append(speed[37:43].max() / max(speed[25:37].max(), speed[43:].max()))
    # No jump at the seam (frame 40): its fastest joint no faster than the motion's own fastest
    # frame before or after it. Per seed it can be: a jump asked right after the prefix may
    # swing the arms up at once (3 seeds of 16 above 1.2x, the two last bundles alike).
    assert np.median(seam_ratios) < 1.0, seam_ratios
    ends = pipe.generate("a person walks forward", lengths=80, seed=2,
                         control={"start_pose": walk[0].tolist(),
                                  "end_pose": walk[79].tolist()})[0].joints
    assert np.linalg.norm(ends[[0, 79]] - walk[[0, 79]], axis=-1).max() < 0.01


def test_generate_rejects_a_bad_control_before_sampling(pipe) -> None:
    with pytest.raises(MlctError, match="outside 0..39"):
        pipe.generate("a person walks", lengths=40, control={"path": [[0, 0, 0], [1, 1, 45]]})
    with pytest.raises(MlctError, match="one text"):
        pipe.generate(["a", "b"], control={"path": [[0, 0]]})


def test_cli_generate_along_a_path_and_an_edit(tmp_path: Path, capsys, walk) -> None:
    path = tmp_path / "path.csv"
    path.write_text("x,z,frame\n0,0,0\n0.3,1.5,39\n", encoding="utf-8")
    out = tmp_path / "walk.npy"
    assert main(["generate", "a person walks forward", "--length", "40", "--seed", "0",
                 "--path", str(path), "--out", str(out), "--quiet"]) == 0
    made = np.load(out)
    assert np.linalg.norm(made[39, 0, [0, 2]] - [0.3, 1.5]) < 0.01
    source = tmp_path / "source.npy"
    np.save(source, walk)
    assert main(["generate", "a person raises both arms", "--edit", str(source), "--parts",
                 "arms", "--seed", "0", "--out", str(tmp_path / "edit.npy"), "--quiet"]) == 0
    edited = np.load(tmp_path / "edit.npy")
    kept = [j for j in range(22) if j not in part_joints("arms", SKELETON)]
    assert np.abs(edited[:, kept] - walk[:, kept]).max() < 0.01
    keys = tmp_path / "keys.json"
    keys.write_text(json.dumps([{"frame": 99, "joint": "nose", "position": [0, 1, 0]}]))
    capsys.readouterr()
    assert main(["generate", "a person waves", "--keyframes", str(keys), "--out",
                 str(tmp_path / "x.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown joint 'nose'" in err and err.count("\n") == 0


def test_http_generate_follows_a_path_and_answers_bad_controls_with_422(pipe) -> None:
    from fastapi.testclient import TestClient

    from mlct.serve import ServeSettings, create_app

    with TestClient(create_app(pipe, ServeSettings(warmup=False))) as client:
        reply = client.post("/generate", json={"text": "a person walks forward", "lengths": 120,
                                               "seed": 3, "control": {"path": PATH}})
        assert reply.status_code == 200, reply.text
        joints = np.array(reply.json()["motions"][0]["joints"])
        frames = [p[2] for p in PATH]
        assert np.linalg.norm(joints[frames, 0][:, [0, 2]] - np.array(PATH)[:, :2],
                              axis=1).max() < 0.01
        for body, message in [
                ({"text": "a person walks", "lengths": 40,
                  "control": {"path": [[0, 0, 0], [1, 1, 99]]}}, "outside 0..39"),
                ({"texts": ["a", "b"], "control": {"path": [[0, 0]]}}, "one text"),
                ({"text": "a person waves", "control": {"keyframes": [{"frame": 1}]}},
                 "no joint positions"),
                ({"text": "a person waves", "control": {"path": "left"}}, "path")]:
            reply = client.post("/generate", json=body)
            assert reply.status_code == 422, (body, reply.text)
            assert message in reply.json()["detail"], reply.json()
