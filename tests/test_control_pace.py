"""Paths met by the text's own motion (generate/control/pace.py): re-timed to the path's pace,
laid along it; on a stepping stick figure, then on the bundled model's walk."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.generate.control import pace

FPS = 20.0


def stepper(frames: int = 120, speed: float = 1.0, stride: float = 0.6) -> np.ndarray:
    """(T, 3, 3): a root moving +Z at `speed` m/s (swaying 2 cm sideways) and two feet, each
    standing still while the other swings past it by one stride."""
    t = np.arange(frames) / FPS
    z = speed * t
    out = np.zeros((frames, 3, 3))
    out[:, 0] = np.stack([0.02 * np.sin(np.pi * z / stride), np.full(frames, 0.9), z], 1)
    for k, side in enumerate((-0.1, 0.1)):
        phase = z / (2 * stride) + 0.5 * k  # each foot's cycle: stand half of it, swing half
        cycle, within = np.floor(phase), phase - np.floor(phase)
        planted = (cycle + 0.5 * k) * 2 * stride
        swing = np.clip(2 * within - 1, 0, 1)
        out[:, k + 1, 0] = side
        out[:, k + 1, 2] = planted + swing * 2 * stride
        out[:, k + 1, 1] = 0.1 * np.sin(np.pi * swing)
    return out


def standing(joints: np.ndarray) -> np.ndarray:
    """(T-1, F) bool: a foot on the floor in both frames of a pair."""
    low = joints[:, 1:, 1] < 1e-6
    return low[1:] & low[:-1]


def slide(joints: np.ndarray) -> float:
    """The largest step of a standing foot between two frames (m)."""
    steps = np.linalg.norm(np.diff(joints[:, 1:, [0, 2]], axis=0), axis=-1)
    return float(steps[standing(joints)].max())


def arc(frames: int, length: float, radius: float) -> np.ndarray:
    """Root targets along a circle turning right, at a constant pace."""
    a = np.linspace(0.0, length / radius, frames)
    return np.stack([radius * (1 - np.cos(a)), radius * np.sin(a)], axis=1)


def test_track_measures_the_root_s_progress_without_its_sway() -> None:
    track = pace.track_of(stepper(), FPS)
    assert track.distance == pytest.approx(119 / FPS, abs=0.02)
    assert np.all(np.diff(track.progress) >= 0)
    assert np.abs(track.direction).max() < np.radians(2)  # straight ahead, sway averaged out
    assert pace.travels(track, 6.0) and not pace.travels(pace.track_of(stepper(speed=0.0), FPS),
                                                             6.0)
    # twice the path: a source twice as long (and SPARE); never more than MAX_FACTOR
    assert pace.frames_to_cover(track, 120, 2 * track.distance) == round(240 * pace.SPARE)
    assert pace.frames_to_cover(track, 120, 100.0) == round(120 * pace.MAX_FACTOR * pace.SPARE)


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_a_source_laid_along_a_faster_or_slower_straight_path_keeps_its_feet(factor) -> None:
    source = stepper(frames=int(120 * factor) + 10)  # 1 m/s, a little longer than needed
    t = np.arange(120)
    targets = np.stack([np.zeros(120), factor * t / FPS], axis=1)  # factor m/s along +Z
    laid = pace.lay_along(source, targets, FPS).joints
    assert laid.shape == (120, 3, 3)
    assert np.abs(laid[:, 0, [0, 2]] - targets).max() < 0.025  # the root on the path (its sway)
    assert slide(laid) < 0.005  # a standing foot stays where it stands
    # the same strides at the path's pace: as many steps as the source made over that distance
    steps = lambda j: int((np.diff(standing(j).astype(int), axis=0) == 1).sum())  # noqa: E731
    covered = stepper(frames=int(120 * factor))
    assert abs(steps(laid) - steps(covered)) <= 1


def test_a_straight_source_laid_along_an_arc_turns_with_it() -> None:
    targets = arc(120, 5.95, radius=2.5)
    laid = pace.lay_along(stepper(frames=130), targets, FPS).joints
    assert np.abs(laid[:, 0, [0, 2]] - targets).max() < 0.03
    # the body turns with the path: at the end each foot is beside the root on the path's
    # normal there (the body's +X turned by the path's heading), on its own side
    end = np.arctan2(*(targets[-1] - targets[-2]))  # ~136 degrees
    normal = np.array([np.cos(end), -np.sin(end)])
    for foot, side in ((1, -0.1), (2, 0.1)):
        assert (laid[-1, foot, [0, 2]] - laid[-1, 0, [0, 2]]) @ normal == pytest.approx(
            side, abs=0.03)
    # a standing foot d behind the root slides sideways at pace * d / radius as the body turns
    # (this stick figure's feet stand up to 0.6 m from it: 1.2 cm a frame; the stance lock of
    # the correction then holds them)
    assert slide(laid) < 0.03


def test_a_source_shorter_than_the_path_holds_its_last_frame() -> None:
    targets = np.stack([np.zeros(60), np.linspace(0.0, 4.0, 60)], axis=1)
    laid = pace.lay_along(stepper(frames=40), targets, FPS).joints  # goes 1.95 m of the 4
    assert np.allclose(laid[-10:], laid[-1]) and laid[-1, 0, 2] == pytest.approx(1.95, abs=0.05)


# ---------------------------------------------------------------- on the bundled model

@pytest.fixture(scope="module")
def pipe():
    import mlct

    return mlct.load()


def along_z(speed: float, frames: int = 120) -> "Control":
    from mlct.generate.control.schema import Control

    at = np.unique(np.r_[np.arange(0, frames, 20), frames - 1])
    return Control(path=np.stack([np.zeros(len(at)), speed * at / FPS], axis=1), path_frames=at)


def test_a_path_at_twice_the_walk_s_speed_is_walked_in_more_steps_not_slid(pipe) -> None:
    from mlct.generate.control.controlled import controlled_motion
    from mlct.motion.gait import steps_per_second
    from mlct.motion.physics import foot_skating_ratio

    text, skeleton = "a person walks forward", pipe.skeleton
    plain = pipe.generate(text, lengths=120, seed=0)[0].joints
    speed = np.linalg.norm(plain[-1, 0, [0, 2]] - plain[0, 0, [0, 2]]) / (119 / FPS)
    control = along_z(2 * speed).check(120, skeleton)
    made = controlled_motion(pipe, text, 120, control, None, 0)
    at = control.path_frames
    before = np.linalg.norm(made.before[at, 0][:, [0, 2]] - control.path, axis=1)
    after = np.linalg.norm(made.motion.joints[at, 0][:, [0, 2]] - control.path, axis=1)
    assert before.mean() < 0.05 and after.max() < 0.01  # the correction has little left to do
    assert steps_per_second(made.motion.joints, skeleton) > 1.6 * steps_per_second(plain,
                                                                                  skeleton)
    assert foot_skating_ratio(made.motion.joints, skeleton) < foot_skating_ratio(plain,
                                                                                skeleton) + 0.05


def test_a_text_that_does_not_travel_is_moved_along_the_path(pipe) -> None:
    from mlct.generate.control.controlled import controlled_motion

    control = along_z(0.4).check(120, pipe.skeleton)
    made = controlled_motion(pipe, "a person waves with the right hand", 120, control, None, 0)
    at = control.path_frames
    assert np.linalg.norm(made.before[-1, 0, [0, 2]] - control.path[-1]) > 1.0  # waved in place
    assert np.abs(made.motion.joints[at, 0][:, [0, 2]] - control.path).max() < 0.01


def test_guidance_without_torch_is_a_one_line_error_naming_the_extra(pipe, monkeypatch) -> None:
    import sys

    from mlct.errors import MissingExtra
    from mlct.generate.control.controlled import ControlMethod, generate_controlled

    monkeypatch.setitem(sys.modules, "torch", None)  # `import torch` fails as without it
    with pytest.raises(MissingExtra, match=r"mlct\[train\]") as raised:
        generate_controlled(pipe, "a person walks forward", 60, along_z(0.5, 60), None, 0,
                            ControlMethod(guide=True))
    assert "\n" not in str(raised.value)


@pytest.mark.slow
def test_without_torch_a_path_is_walked_and_keyframes_name_the_extra(tmp_path) -> None:
    """The pace needs no gradients: on a light install (torch unimportable, as
    tests/test_light_install.py makes it) a path is walked; keyframes, met by sampling
    candidates through torch, are one line naming the extra."""
    import json
    import os
    import subprocess
    import sys
    import textwrap

    (tmp_path / "path.json").write_text("[[0, 0], [0, 2], [1, 3]]", encoding="utf-8")
    (tmp_path / "keys.json").write_text(json.dumps(
        [{"frame": 40, "joint": "right_wrist", "position": [0.3, 1.6, 0.3]}]), encoding="utf-8")
    code = textwrap.dedent("""
        import sys

        class NoTorch:
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] == "torch":
                    raise ModuleNotFoundError(f"No module named {name!r}", name=name)

        sys.meta_path.insert(0, NoTorch())
        from mlct.cli import main

        base = ["generate", "a person walks forward", "--seconds", "5", "--seed", "0", "--quiet"]
        print(main([*base, "--path", "path.json", "--out", "p.npy"]))
        print(main([*base, "--keyframes", "keys.json", "--out", "k.npy"]))
        print("torch" in sys.modules)
    """)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    env.pop("MLCT_BACKEND", None)  # the suite pins torch (conftest.py); auto is the default
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.stdout.split()[-3:] == ["0", "2", "False"], done.stderr[-2000:]
    path = np.load(tmp_path / "p.npy")
    assert np.linalg.norm(path[-1, 0, [0, 2]] - [1.0, 3.0]) < 0.01
    errors = [line for line in done.stderr.splitlines() if line.startswith("mlct: error:")]
    assert len(errors) == 1 and "keyframes" in errors[0] and "mlct[train]" in errors[0], errors
