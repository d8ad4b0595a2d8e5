"""Keep-going (generate/compose/keep_going.py): locomotion asked for longer than its natural length is
chained from takes instead of stopping; on hand-built walkers, and through the bundled model."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.generate.compose.keep_going import (ground_speed, is_gait, keep_going, moving_stretch,
                                      names_an_end, retime, segment_count, stops_early)
from mlct.motion.skeleton import HUMANML3D

FPS = HUMANML3D.fps
BLEND = 15


def rest_pose() -> np.ndarray:
    """(J, 3) the natural rest pose by forward kinematics, feet on y = 0."""
    offsets = HUMANML3D.rest_offsets
    pose = np.zeros((HUMANML3D.n_joints, 3))
    for joint, parent in enumerate(HUMANML3D.parents):
        if parent >= 0:
            pose[joint] = pose[parent] + offsets[joint]
    return pose - [0.0, pose[:, 1].min(), 0.0]


def walker(seconds: float, pace: float = 1.0, phase: float = 0.0, stop_at: float | None = None,
           lift: float = 0.0) -> np.ndarray:
    """(T, J, 3) a take that starts from rest, walks +Z at `pace` m/s with alternating feet
    (2 strides a second), and slows to a stop 0.6 s before its end (or at `stop_at`); the
    whole take raised by `lift` metres (a generated take's floor is not always at 0)."""
    frames = int(round(seconds * FPS))
    t = np.arange(frames) / FPS
    end = seconds - 0.6 if stop_at is None else stop_at
    speed = pace * np.clip(np.minimum((t - 0.3) / 0.5, (end - t) / 0.5), 0.0, 1.0)
    z = np.concatenate([[0.0], np.cumsum(speed[1:]) / FPS])
    pose = rest_pose()
    joints = np.repeat(pose[None], frames, axis=0)
    joints[:, :, 2] += z[:, None]
    swing = np.sin(2 * np.pi * 1.0 * t + phase) * speed / max(pace, 1e-9)
    for side, sign in ((HUMANML3D.foot_left, 1.0), (HUMANML3D.foot_right, -1.0)):
        for joint in side:
            joints[:, joint, 2] += 0.25 * sign * swing
            joints[:, joint, 1] += 0.08 * np.clip(sign * swing, 0.0, None)  # the swing foot up
    joints[:, :, 1] += lift
    return joints


def test_names_an_end():
    for text in ("a person walks forward four steps", "someone jogs 3 laps", "takes a step back",
                 "walks ten meters forward", "hops twice", "walks a few steps forward",
                 "a man runs 5 m", "the figure rotates to face the left",
                 "someone turns around while walking", "a dancer spins"):
        assert names_an_end(text), text
    for text in ("a person walks forward", "someone walks in a circle to the left",
                 "a man strolls down the street", "the woman jogs ahead at a steady pace"):
        assert not names_an_end(text), text


def test_ground_speed_reads_the_pelvis_pace():
    joints = walker(6.0, pace=1.2)
    speed = ground_speed(joints, FPS)
    assert speed.shape == (len(joints),)
    assert speed[:5].max() < 0.05  # standing at the start
    assert abs(np.median(speed[30:80]) - 1.2) < 0.05


def test_stops_early_needs_a_stop_past_the_natural_length():
    stopped = walker(8.0, stop_at=4.0)  # walks 4 s of an 8-s clip, then stands
    assert stops_early(stopped, FPS, natural_seconds=4.5,
                       skeleton=HUMANML3D)
    # asked within a second of its natural length: stopping is the action's own end
    assert not stops_early(stopped[:100], FPS, natural_seconds=4.5,
                       skeleton=HUMANML3D)
    # walks to the end: nothing to fix
    assert not stops_early(walker(8.0, stop_at=8.5), FPS, natural_seconds=4.5,
                       skeleton=HUMANML3D)
    # never moved over the ground (an arm action): not locomotion
    still = np.repeat(rest_pose()[None], 160, axis=0)
    assert not stops_early(still, FPS, natural_seconds=3.0, skeleton=HUMANML3D)


def spinner(seconds: float, spin_for: float, rate_deg: float = 200.0, radius: float = 0.1
            ) -> np.ndarray:
    """(T, J, 3) a body spinning on the spot at rate_deg a second for spin_for seconds (its
    pelvis circling `radius` m around the feet, ~0.35 m/s), then standing."""
    from mlct.generate.compose.long_motion import _turn_y

    frames = int(round(seconds * FPS))
    t = np.minimum(np.arange(frames) / FPS, spin_for)
    angle = np.radians(rate_deg) * t
    joints = _turn_y(np.repeat(rest_pose()[None], frames, axis=0), angle[:, None])
    joints[:, :, 0] += radius * np.cos(angle)[:, None]
    joints[:, :, 2] += radius * np.sin(angle)[:, None]
    return joints


def test_a_spin_on_the_spot_is_not_locomotion():
    """A spin moves the pelvis fast enough to pass for a gait; it goes nowhere and turns far
    faster than a circle walk, so it is left to stop."""
    spin = spinner(6.0, spin_for=2.2)
    assert np.median(ground_speed(spin, FPS)[10:40]) > 0.25
    assert not stops_early(spin, FPS, natural_seconds=2.6, skeleton=HUMANML3D)


def test_one_long_jump_is_not_a_gait():
    """The pelvis of a long jump forward rises to ~1.5 m/s and falls within a second: moving
    enough and straight, but not a steady pace."""
    frames = 190
    t = np.arange(frames) / FPS
    speed = 1.5 * np.exp(-((t - 1.05) / 0.3) ** 2) + 0.3 * ((t > 0.4) & (t < 1.55))
    joints = np.repeat(rest_pose()[None], frames, axis=0)
    joints[:, :, 2] += (np.cumsum(speed) / FPS)[:, None]
    assert np.percentile(ground_speed(joints, FPS)[10:34], 25) > 0.25
    assert not stops_early(joints, FPS, natural_seconds=2.2, skeleton=HUMANML3D)


def test_moving_stretch_drops_the_start_up_and_the_slow_down():
    first, last = moving_stretch(walker(4.5), FPS)
    assert 6 <= first <= 16 and 66 <= last <= 80


def test_segment_count_covers_the_length():
    for frames, take in ((140, 90), (190, 73), (190, 45)):
        count = segment_count(frames, take, BLEND)
        # even if each later take added only half of itself less the blend
        assert take + (count - 1) * (take - take // 2 - BLEND) >= frames


def test_keep_going_walks_the_whole_length_without_a_dip():
    frames = 190
    takes = [walker(4.5, phase=k * 1.3, lift=0.03 * (k % 2)) for k in range(6)]
    joints, seams = keep_going(takes, frames, BLEND, HUMANML3D)
    assert joints.shape == (frames, HUMANML3D.n_joints, 3)
    assert len(seams) >= 2 and all(0 < a < b < frames for a, b in zip(seams, seams[1:]))
    speed = ground_speed(joints, FPS)
    assert speed[:3].max() < 0.1  # from rest, as the first take
    assert speed[-3:].max() < 0.2  # to rest, as the last take ends
    assert speed[25:-25].min() > 0.6  # no stop or deep dip at the seams
    travel = joints[-1, 0, 2] - joints[0, 0, 2]
    assert travel > 0.8 * 1.0 * (frames / FPS - 1.5)  # ~1 m/s for all but the ramps
    # one floor: the takes raised by 3 cm were brought down to the first take's floor
    feet = list(HUMANML3D.foot_left) + list(HUMANML3D.foot_right)
    lowest = joints[:, feet, 1].min(axis=1)
    assert np.abs(lowest - np.median(lowest)).max() < 0.01
    # a shorter clip from the same takes: the first take cut short, still no dip
    assert ground_speed(keep_going(takes, 120, BLEND, HUMANML3D)[0], FPS)[25:-25].min() > 0.6


def test_keep_going_gives_up_when_the_takes_fall_short():
    assert keep_going([walker(4.5), walker(4.5)], 400, BLEND, HUMANML3D) is None
    assert keep_going([walker(4.5)], 120, BLEND, HUMANML3D) is None


def test_retime_keeps_the_ends_and_changes_the_tempo():
    joints = walker(4.0)
    out = retime(joints, 84)
    assert out.shape == (84, HUMANML3D.n_joints, 3)
    np.testing.assert_allclose(out[0], joints[0])
    np.testing.assert_allclose(out[-1], joints[-1])
    assert retime(joints, len(joints)) is joints


@pytest.fixture(scope="module")
def generator():
    import mlct

    return mlct.load(backend="torch")


def test_the_bundled_model_keeps_jogging(generator):
    """The bundle's jogs last 3.2-4 s in the data: asked for 8 s, the model alone stands still
    for the last 4 s; with keep-going it jogs on (the ground covered in the last 2 s at least
    half that of the first 2 s) and ends within a stride's retiming of the length."""
    fps = generator.skeleton.fps
    generator.keep_going = False
    try:
        before = generator.generate("a person jogs forward", seconds=8.0, seed=0)[0].joints
    finally:
        generator.keep_going = True
    after = generator.generate("a person jogs forward", seconds=8.0, seed=0)[0].joints
    assert len(after) == len(before) == int(round(8.0 * fps))

    def travel(joints: np.ndarray) -> float:
        return float(np.linalg.norm(np.diff(joints[:, 0, [0, 2]], axis=0), axis=1).sum())
    two = int(2 * fps)
    assert travel(before[-two:]) < 0.1 * travel(before[:two])
    assert travel(after[-two:]) > 0.5 * travel(after[:two])
    # a chained motion, as a chain of prompts is: its seams stay within the takes' speeds
    from mlct.generate.compose.long_motion import LongMotion, seam_speeds

    made = generator.generate("a person jogs forward", seconds=8.0, seed=0)[0]
    assert isinstance(made, LongMotion) and len(made.seams) >= 1
    speeds = seam_speeds(made)
    assert speeds["seam_max"] <= 1.05 * speeds["segments_max"]


def test_the_bundled_model_leaves_ending_actions_alone(generator):
    for text in ("a person jumps", "a person walks forward four steps"):
        generator.keep_going = False
        try:
            before = generator.generate(text, seconds=8.0, seed=0)[0].joints
        finally:
            generator.keep_going = True
        after = generator.generate(text, seconds=8.0, seed=0)[0].joints
        np.testing.assert_array_equal(before, after)


def test_verbose_says_when_a_gait_kept_going(tmp_path, capsys):
    from mlct.cli import main

    assert main(["generate", "a person jogs forward", "--seconds", "8", "--seed", "0",
                 "--backend", "torch", "--verbose", "--out", str(tmp_path / "v.npy")]) == 0
    assert "'a person jogs forward' kept going:" in capsys.readouterr().err
    assert main(["generate", "a person jumps", "--seconds", "8", "--seed", "0", "--backend",
                 "torch", "--verbose", "--out", str(tmp_path / "j.npy")]) == 0
    assert "kept going" not in capsys.readouterr().err


def test_the_cli_keeps_going_unless_told_not_to(tmp_path):
    from mlct.cli import main

    for name, flags in (("on.npy", []), ("off.npy", ["--no-keep-going"])):
        assert main(["generate", "a person jogs forward", "--seconds", "8", "--seed", "0",
                     "--backend", "torch", "--out", str(tmp_path / name), *flags]) == 0
    on, off = np.load(tmp_path / "on.npy"), np.load(tmp_path / "off.npy")
    assert on.shape == off.shape == (160, 22, 3)
    last = slice(-40, None)
    moved = [float(np.linalg.norm(np.diff(j[last, 0, [0, 2]], axis=0), axis=1).sum())
             for j in (on, off)]
    assert moved[0] > 2.0 and moved[1] < 0.2  # jogging on against standing still


def test_a_gait_goes_past_the_window_and_nothing_else_does(generator):
    """Past the model's 9.8-s window only a gait is made (as chained takes); other one-action
    prompts get the window's one-line error, and so does a gait with keep-going off."""
    from mlct.errors import MlctError

    fps = generator.skeleton.fps
    walk = generator.generate("a person walks forward", seconds=15.0, seed=0)[0].joints
    assert walk.shape == (int(15 * fps), 22, 3)
    speed = ground_speed(walk, fps)
    assert np.percentile(speed[int(fps):-int(fps)], 10) > 0.5  # walking throughout
    for text in ("a person jumps", "a person walks forward four steps"):
        with pytest.raises(MlctError, match="only a gait"):
            generator.generate(text, seconds=15.0, seed=0)
    with pytest.raises(MlctError, match="only a gait"):  # a sequence given whole: not a gait
        generator.generate("a person walks forward, then squats", seconds=15.0, seed=0,
                           split_actions=False)
    with pytest.raises(MlctError, match="up to 120 s"):
        generator.generate("a person walks forward", seconds=121.0, seed=0)
    generator.keep_going = False
    try:
        with pytest.raises(MlctError, match=r"outside 1\.\.196"):
            generator.generate("a person walks forward", seconds=15.0, seed=0)
    finally:
        generator.keep_going = True


def test_a_sequence_or_a_chain_may_hold_a_gait_past_the_window(generator):
    """'walks forward, then jumps' in 15 s gives the walk its ~11 s (chained takes) and the
    jump the rest; a chain of prompts may give a walk 15 s; a part that is not a gait may not
    pass the window, and the error names it."""
    from mlct.errors import MlctError
    from mlct.generate.compose.long_motion import generate_long

    fps = generator.skeleton.fps
    both = generator.generate("a person walks forward, then jumps", seconds=15.0, seed=0)[0]
    assert both.joints.shape[0] == int(15 * fps)
    assert ground_speed(both.joints, fps)[int(2 * fps):int(8 * fps)].min() > 0.4  # still walking
    chain = generate_long(generator, ["a person walks forward", "a person waves"], [15.0, 3.0],
                          seed=0)
    assert chain.joints.shape[0] == int(18 * fps)
    with pytest.raises(MlctError, match="'a person claps': length .* only a gait"):
        generator.generate("a person jumps, then claps", seconds=25.0, seed=0)


def test_the_takes_seeds_wrap_at_the_largest_seed(generator):
    from mlct.generate.seeds import MAX_SEED

    made = generator.generate("a person jogs forward", seconds=8.0, seed=MAX_SEED)[0]
    assert made.seed == MAX_SEED and made.joints.shape[0] == 160 and len(made.seams) >= 1


def test_a_walk_that_stops_before_its_natural_length_is_a_gait_by_its_steps():
    """A decoder may end a walk's clip before the duration model's natural length (the 96 / 96
    decoder stopped "a person walks forward" at 4.3 s of 5.0): judged over its moving stretch,
    it is a gait when its feet alternate there, and it is kept going; the same root path with
    the feet moving together (no steps) is not."""
    from mlct.motion.gait import foot_swaps

    walk = walker(9.0, stop_at=4.0)
    assert foot_swaps(walk[10:76], HUMANML3D) >= 4
    assert is_gait(walk, FPS, natural_seconds=4.99, skeleton=HUMANML3D)
    assert stops_early(walk, FPS, natural_seconds=4.99, skeleton=HUMANML3D)
    shuffle = walk.copy()
    for side in (HUMANML3D.foot_left, HUMANML3D.foot_right):
        for joint in side:
            shuffle[:, joint, 1] = walk[:, joint, 1].min()  # both feet on the floor throughout
    assert foot_swaps(shuffle, HUMANML3D) == 0
    assert not is_gait(shuffle, FPS, natural_seconds=4.99, skeleton=HUMANML3D)
