"""Physical read-outs and the label checks: known answers on hand-built and composed motions."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.data.synth.actions import Action, Script
from mlct.data.synth.compose import compose
from mlct.data.synth.motions import Style
from mlct.data.synth.rig import make_rig
from mlct.eval import readouts as ro
from mlct.motion.skeleton import HUMANML3D as SK

FPS = SK.fps
N = 40  # frames of the hand-built motions (2 s)


def _script(*actions: tuple[str, dict], concurrent: tuple[str, dict] | None = None) -> Script:
    return Script(tuple(Action(f, p) for f, p in actions),
                  None if concurrent is None else Action(*concurrent))


def _compose(script: Script, seed: int = 0):
    """Positions (T, 22, 3) in metres of a benchmark script, facing +Z, and its segments."""
    rig = make_rig(SK)
    composed = compose(script, rig, Style(), np.random.default_rng(seed), FPS)
    return composed.positions / rig.scale, composed.segments


def _motion(family: str, **params) -> np.ndarray:
    return _compose(_script((family, params)))[0]


def _label(script: Script, segments, n_frames: int) -> dict:
    """A labels.jsonl record for a composed script, as the benchmark writes it."""
    return {"actions": [dict(a.to_json(), start=s / FPS, end=e / FPS)
                        for a, (s, e) in zip(script.actions, segments)],
            "concurrent": None if script.concurrent is None else script.concurrent.to_json(),
            "frames": n_frames}


@pytest.fixture(scope="module")
def pose() -> np.ndarray:
    """A standing pose (22, 3) in metres, facing exactly +Z with its left on +X, feet on the
    floor (the benchmark's idle posture noise turns it by a fraction of a degree: undone)."""
    standing = _motion("stand")[0]
    return _turned(standing, -ro.heading(standing[None]))[0]


def _still(pose: np.ndarray, n: int = N) -> np.ndarray:
    return np.repeat(pose[None], n, axis=0).copy()


def _ramp(n: int = N) -> np.ndarray:
    """(n,) 0 -> 1 smoothly, zero slope at the ends."""
    x = np.linspace(0.0, 1.0, n)
    return x * x * (3 - 2 * x)


def _turned(pose: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """The pose rotated about the vertical through its pelvis by `angles` (T,) radians
    (positive turns +Z towards +X: to the person's left)."""
    c, s = np.cos(angles), np.sin(angles)
    local = pose - pose[0] * np.array([1.0, 0.0, 1.0])
    x, z = local[None, :, 0], local[None, :, 2]
    out = np.repeat(local[None], len(angles), axis=0)
    out[..., 0] = c[:, None] * x + s[:, None] * z
    out[..., 2] = -s[:, None] * x + c[:, None] * z
    return out + pose[0] * np.array([1.0, 0.0, 1.0])


# ---------------------------------------------------------------------------- read-outs

def test_a_still_pose_reads_zero(pose):
    r = ro.read_all(_still(pose))
    for name in ("forward_displacement", "lateral_displacement", "heading_change",
                 "pelvis_rise", "pelvis_drop", "foot_lift.left", "foot_travel.right"):
        assert r[name] == pytest.approx(0.0, abs=1e-9), name
    assert r["airborne_frames"] == r["foot_swaps"] == r["hand_gap_minima"] == 0
    assert r["wrist_height.left"] < -0.5 and r["wrist_height.right"] < -0.5  # arms hang


def test_translation_reads_as_forward_and_lateral_displacement(pose):
    joints = _still(pose)
    joints += _ramp()[:, None, None] * np.array([0.5, 0.0, 1.0])  # +Z forward, +X the left
    assert ro.forward_displacement(joints) == pytest.approx(1.0, abs=1e-6)
    assert ro.lateral_displacement(joints) == pytest.approx(0.5, abs=1e-6)
    assert ro.pelvis_path(joints) == pytest.approx(np.hypot(0.5, 1.0), rel=1e-3)
    # Turned to face +X first, the same +X travel is forward and the +Z travel to the right.
    turned = _turned(pose, np.full(N, np.pi / 2))
    turned += _ramp()[:, None, None] * np.array([0.5, 0.0, 1.0])
    assert ro.forward_displacement(turned) == pytest.approx(0.5, abs=1e-6)
    assert ro.lateral_displacement(turned) == pytest.approx(-1.0, abs=1e-6)


def test_heading_change_is_left_positive_and_unwrapped(pose):
    assert ro.heading_change(_turned(pose, np.pi / 2 * _ramp())) == pytest.approx(np.pi / 2)
    assert ro.heading_change(_turned(pose, -np.pi / 2 * _ramp())) == pytest.approx(-np.pi / 2)
    assert ro.heading_change(_turned(pose, 2.5 * np.pi * _ramp(80))) == pytest.approx(2.5 * np.pi)


def test_benchmark_turns_and_side_steps_have_the_documented_signs():
    assert ro.heading_change(_motion("turn", side="left", angle=90)) == pytest.approx(
        np.pi / 2, abs=np.radians(8))
    assert ro.heading_change(_motion("turn", side="right", angle=90)) < -1.2
    assert ro.lateral_displacement(_motion("side_step", side="left", steps=3)) > 0.3
    assert ro.lateral_displacement(_motion("side_step", side="right", steps=3)) < -0.3


def test_lifted_body_rises_and_is_airborne(pose):
    joints = _still(pose)
    lift = 0.3 * np.sin(np.pi * np.clip((np.arange(N) - 10) / 10, 0, 1))  # up over frames 10-20
    joints[..., 1] += lift[:, None]
    assert ro.pelvis_rise(joints) == pytest.approx(lift.max(), abs=1e-9)
    assert ro.pelvis_drop(joints) == pytest.approx(0.0, abs=1e-9)
    assert ro.airborne_frames(joints) == int((lift > 0.05).sum()) > 0
    assert ro.airborne_episodes(joints) == 1
    assert ro.foot_lift(joints)["left"] == pytest.approx(lift.max(), abs=1e-9)


def test_lowered_pelvis_drops_and_dips(pose):
    joints = _still(pose, 60)
    legs = [SK.index(f"{s}_{j}") for s in ("left", "right") for j in ("knee", "ankle", "foot")]
    upper = [j for j in range(SK.n_joints) if j not in legs]
    depth = 0.3 * np.sin(np.pi * np.clip((np.arange(60) - 10) / 40, 0, 1))
    joints[:, upper, 1] -= depth[:, None]
    assert ro.pelvis_drop(joints) == pytest.approx(depth.max(), abs=1e-9)
    assert ro.pelvis_dips(joints) == 1
    assert ro.low_hold(joints) == pytest.approx((depth > 0.15).sum() / FPS)


def test_alternating_feet_swap_lift_and_travel(pose):
    joints = _still(pose, 60)
    t = np.arange(60)
    for side, phase in (("left", 0.0), ("right", np.pi)):
        # After 5 standing frames, each foot lifts 0.2 m in turn (the left first).
        up = 0.2 * np.clip(np.sin(2 * np.pi * (t - 5) / 20 + phase), 0, None) * (t >= 5)
        for joint in SK.foot_left if side == "left" else SK.foot_right:
            joints[:, joint, 1] += up
    joints[:, SK.foot_left[0], 2] += 0.3 * _ramp(60)  # the left ankle moves 0.3 m forward
    assert ro.foot_lift(joints)["left"] == pytest.approx(0.2, abs=1e-3)
    assert ro.foot_swaps(joints) == 5  # left up, right up, ... : the lower foot changes 5 times
    assert ro.foot_travel(joints)["left"] == pytest.approx(0.3, abs=1e-6)
    assert ro.foot_travel(joints)["right"] == pytest.approx(0.0, abs=1e-9)
    # Both feet side by side, moving by less than the hysteresis: no swaps.
    jitter = _still(pose)
    jitter[:, SK.foot_left[0], 1] += 0.02 * np.sin(np.arange(N))
    assert ro.foot_swaps(jitter) == 0


def test_wrists_height_reach_and_gaps(pose):
    joints = _still(pose)
    head = pose[SK.index("head")]
    left, right = SK.index("left_wrist"), SK.index("right_wrist")
    joints[20:, left] = head + np.array([0.2, 0.2, 0.0])  # left hand up beside the head
    joints[:, right, 2] += 0.4 * _ramp()  # right hand forward
    heights, reach = ro.wrist_height(joints), ro.wrist_reach(joints)
    assert heights["left"] == pytest.approx(0.2) and heights["right"] < -0.5
    assert reach["right"] - reach["left"] > 0.35
    # Hands brought together twice (a clap): two separate minima of the gap.
    clap = _still(pose)
    middle = 0.5 * (pose[left] + pose[right])
    closed = np.clip(np.sin(2 * np.pi * np.arange(N) / N * 2), 0, None)[:, None]
    clap[:, left] = pose[left] + closed * (middle - pose[left])
    clap[:, right] = pose[right] + closed * (middle - pose[right])
    assert ro.hand_gap_minima(clap) == 2
    assert ro.min_hand_gap(clap) < 0.01


def test_torso_pitch_and_side_lean(pose):
    pelvis = pose[0]
    upper = [SK.index(n) for n in ("spine1", "spine2", "spine3", "neck", "head", "left_collar",
                                   "right_collar", "left_shoulder", "right_shoulder",
                                   "left_elbow", "right_elbow", "left_wrist", "right_wrist")]
    base = ro.torso_pitch(_still(pose))

    def leaned(axis: int, angle: float) -> np.ndarray:
        joints = _still(pose)
        for t, a in enumerate(angle * _ramp()):
            c, s = np.cos(a), np.sin(a)
            rel = joints[t, upper] - pelvis
            if axis == 0:  # about +x: +y towards +z, a forward lean
                y, z = rel[:, 1].copy(), rel[:, 2].copy()
                rel[:, 1], rel[:, 2] = c * y - s * z, s * y + c * z
            else:  # about -z: +y towards +x, a lean to the person's left
                x, y = rel[:, 0].copy(), rel[:, 1].copy()
                rel[:, 0], rel[:, 1] = c * x + s * y, -s * x + c * y
            joints[t, upper] = pelvis + rel
        return joints

    assert ro.torso_pitch(leaned(0, 0.6)) - base == pytest.approx(0.6, abs=0.03)
    lean = ro.torso_side_lean(leaned(2, 0.3))
    assert lean["left"] == pytest.approx(0.3, abs=0.03) and lean["right"] < 0.05


def test_read_all_has_every_readout_and_bad_input_raises(pose):
    r = ro.read_all(_still(pose))
    assert {"forward_displacement", "heading_change", "airborne_frames", "foot_lift.left",
            "wrist_height.right", "torso_pitch", "min_hand_gap"} <= set(r)
    assert all(isinstance(v, float) for v in r.values())
    with pytest.raises(ValueError, match="shape"):
        ro.read_all(np.zeros((10, 21, 3)))
    with pytest.raises(ValueError, match="shape"):
        ro.forward_displacement(pose)  # one pose, no time axis
    with pytest.raises(ValueError, match="metres"):
        ro.read_all(_still(pose) * 1000.0)  # millimetres


# ---------------------------------------------------------------------------- checks

def _passes(joints: np.ndarray, family: str, **params) -> bool:
    readings = ro.read_all(joints)
    return all(check(readings) for check in ro.checks_for({"family": family, "params": params}))


def test_wave_checks_tell_the_hands_apart():
    left, right = _motion("wave", hand="left", count=3), _motion("wave", hand="right", count=3)
    assert _passes(left, "wave", hand="left", count=3)
    assert not _passes(right, "wave", hand="left", count=3)
    assert _passes(right, "wave", hand="right", count=3)
    assert not _passes(left, "wave", hand="both", count=3)
    assert not _passes(left, "wave", hand="left", count=2)  # three waves, not two


def test_a_standing_clip_fails_the_action_checks():
    stand = _motion("stand")
    assert _passes(stand, "stand")
    for family, params in [("walk", {"speed": "normal", "direction": "forward"}),
                           ("jump", {"mode": "in_place", "count": 1}), ("kick", {"leg": "left"}),
                           ("wave", {"hand": "left"}), ("turn", {"side": "left", "angle": 90}),
                           ("squat", {}), ("clap", {}), ("hop", {"leg": "right"})]:
        assert not _passes(stand, family, **params), family


def test_checks_pass_their_own_composed_motions_and_not_the_mirrored_ones():
    cases = [("walk", {"speed": "normal", "direction": "forward"}, None),
             ("jump", {"mode": "forward", "count": 2}, ("mode", "in_place")),
             ("kick", {"leg": "right", "count": 1}, ("leg", "left")),
             ("hop", {"leg": "left", "count": 3}, ("leg", "right")),
             ("kneel", {"leg": "left"}, ("leg", "right")),
             ("punch", {"hand": "left", "count": 2}, ("hand", "right")),
             ("turn", {"side": "right", "angle": 135}, ("angle", 90))]
    for family, params, wrong in cases:
        joints = _motion(family, **params)
        assert _passes(joints, family, **params), family
        if wrong:
            assert not _passes(joints, family, **dict(params, **{wrong[0]: wrong[1]})), family
    assert not _passes(_motion("walk_backward", speed="normal"), "walk", speed="normal",
                       direction="forward")


def test_unknown_family_raises():
    with pytest.raises(ValueError, match="fly"):
        ro.checks_for({"family": "fly", "params": {}})


def test_evaluate_label_judges_each_action_in_its_window():
    script = _script(("walk", {"speed": "normal", "direction": "forward"}),
                     ("turn", {"side": "left", "angle": 90}), ("squat", {"count": 2}))
    joints, segments = _compose(script)
    label = _label(script, segments, len(joints))
    results = ro.evaluate_label(joints, label)
    assert results and all(ok for _, ok in results), [n for n, ok in results if not ok]
    assert {name.split(":")[0] for name, _ in results} == {"0", "1", "2"}
    assert ro.passes(joints, label)
    # The same motion under a label with the turn to the other side fails only that check.
    wrong = dict(label, actions=[dict(a) for a in label["actions"]])
    wrong["actions"][1]["params"] = {"side": "right", "angle": 90}
    assert [name for name, ok in ro.evaluate_label(joints, wrong) if not ok] == ["1:turn.heading"]
    assert not ro.passes(joints, wrong)


def test_evaluate_label_checks_the_concurrent_action_over_the_clip():
    script = _script(("walk", {"speed": "fast", "direction": "forward"}),
                     concurrent=("raise_arms", {"hand": "right"}))
    joints, segments = _compose(script)
    label = _label(script, segments, len(joints))
    assert ro.passes(joints, label)
    assert any(name.startswith("+:raise_arms") for name, _ in ro.evaluate_label(joints, label))
    label["concurrent"] = {"family": "raise_arms", "params": {"hand": "left"}}
    assert not ro.passes(joints, label)


def test_windows_split_at_the_cross_fades_and_scale_with_length():
    label = {"frames": 100, "actions": [{"start": 0.3, "end": 2.5}, {"start": 2.1, "end": 4.7}]}
    assert ro.action_windows(label, 100) == [(0, 46), (46, 100)]
    assert ro.action_windows(label, 200) == [(0, 92), (92, 200)]  # a clip twice as long
    assert ro.action_windows(label, 100, margin=0.1) == [(0, 48), (44, 100)]


def test_in_order_judge_finds_the_cut_and_keeps_the_order():
    script = _script(("walk", {"speed": "normal", "direction": "forward"}),
                     ("squat", {"count": 1}))
    joints, segments = _compose(script)
    actions = [a.to_json() for a in script.actions]
    results = ro.evaluate_in_order(joints, actions)
    assert results and all(ok for _, ok in results), [n for n, ok in results if not ok]
    assert {name.split(":")[0] for name, _ in results} == {"0", "1"}
    # the same actions asked in the other order: no cut makes the squat come first
    assert not all(ok for _, ok in ro.evaluate_in_order(joints, actions[::-1]))
    # a motion that only walks does not pass "walks, then squats" anywhere
    walk_only = _motion("walk", speed="normal", direction="forward")
    assert not all(ok for _, ok in ro.evaluate_in_order(walk_only, actions))


def test_in_order_judge_passes_where_equal_halves_cut_the_action():
    script = _script(("jump", {"mode": "in_place", "count": 1}), ("walk", {"speed": "normal", "direction": "forward"}))
    joints, segments = _compose(script)
    actions = [a.to_json() for a in script.actions]
    # a long idle lead-in moves the jump past the middle: equal halves judge it as walking
    lead = np.repeat(joints[:1], len(joints), axis=0)
    late = np.concatenate([lead, joints])
    halves = {"actions": [dict(a, start=i * len(late) / 2 / FPS, end=(i + 1) * len(late) / 2 / FPS)
                          for i, a in enumerate(actions)], "concurrent": None}
    assert not ro.passes(late, halves)
    assert all(ok for _, ok in ro.evaluate_in_order(late, actions))


def test_in_order_judge_rejects_a_clip_too_short_for_its_actions(pose):
    with pytest.raises(ValueError, match="too short"):
        ro.evaluate_in_order(_still(pose, 30), [{"family": "stand"}] * 2)
