"""The families benchmark version 3 adds: their motions are physical, their read-outs pass their
own ground truth and reject the other families' motions, and version 2 is remade as it was."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mlct.data.synth.actions import (ENDS_DOWN, FAMILIES, FAMILIES_BY_VERSION, FAMILY_PARAMS,
                                     NEW_FAMILIES, STARTS_DOWN, Action, Script, sample_script)
from mlct.data.synth.build import make_motion
from mlct.data.synth.compose import compose
from mlct.data.synth.motions import Style
from mlct.data.synth.rig import make_rig
from mlct.eval import readouts as ro
from mlct.motion.skeleton import HUMANML3D as SK

RIG = make_rig(SK)
SEEDS = 3  # styles per parameter combination


def _combos(family: str) -> list[dict]:
    spec = FAMILY_PARAMS[family]
    return [dict(zip(spec, values)) for values in itertools.product(*spec.values())]


def _motion(family: str, params: dict, seed: int = 0, *more: tuple[str, dict]) -> np.ndarray:
    """Positions (T, 22, 3) in metres of a script, with the benchmark's range of styles."""
    rng = np.random.default_rng([seed, 7])
    style = Style(amplitude=float(rng.uniform(0.85, 1.15)), tempo=float(rng.uniform(0.85, 1.15)),
                  arm_length=RIG.arm_length, shoulder_x=RIG.shoulder_x)
    script = Script(tuple(Action(f, p) for f, p in ((family, params), *more)))
    return compose(script, RIG, style, rng, SK.fps).positions / RIG.scale


def _passes(readings: dict, family: str, params: dict) -> bool:
    """Whether read-outs (ro.read_all's, made once per motion) pass a family's checks."""
    return all(check(readings) for check in ro.checks_for({"family": family, "params": params}))


@pytest.fixture(scope="module")
def ground_truth() -> dict[str, list[tuple[dict, np.ndarray, dict]]]:
    """Every new family: each parameter combination in SEEDS styles, with the read-outs (made
    once)."""
    out = {f: [(p, _motion(f, p, seed)) for p in _combos(f) for seed in range(SEEDS)]
           for f in NEW_FAMILIES}
    return {f: [(p, joints, ro.read_all(joints)) for p, joints in made]
            for f, made in out.items()}


@pytest.fixture(scope="module")
def others() -> list[tuple[str, dict, dict]]:
    """The read-outs of one motion of every parameter combination (up to 6) of every family."""
    return [(f, p, ro.read_all(_motion(f, p, 11))) for f in FAMILIES for p in _combos(f)[:6]]


def test_new_motions_keep_bone_lengths_and_touch_the_floor(ground_truth):
    for family, motions in ground_truth.items():
        for _, joints, _ in motions:
            bones = np.linalg.norm(joints[:, 1:] - joints[:, list(SK.parents[1:])], axis=-1)
            assert np.abs(bones - SK.bone_lengths[1:]).max() < 1e-9, family
            lowest = joints[..., 1].min(axis=1)
            assert lowest.min() > -1e-9 and np.percentile(lowest, 95) < 0.06, family


def test_floor_poses_rest_on_the_floor_at_human_heights(ground_truth):
    for params, joints, readings in ground_truth["lie_down"]:
        end = joints[-1]
        assert 0.1 < end[0, 1] < 0.2  # the pelvis, lying on the back
        assert end[[3, 6, 9, 12], 1].max() < 0.2  # the spine along the floor
        assert readings["end_chest_up"] > 0.9
    for params, joints, _ in ground_truth["sit_floor"]:
        assert 0.12 < joints[-1, 0, 1] < 0.26 and 0.6 < joints[-1, 15, 1] < 0.95  # pelvis, head
    for params, joints, _ in ground_truth["get_up"]:
        assert joints[0, 0, 1] < 0.2 and joints[-1, 0, 1] > 0.85
    for params, joints, _ in ground_truth["push_up"]:  # a plank on hands and toes
        plank = joints[:, 0, 1] < 0.4
        assert plank.sum() > 2 * SK.fps
        assert np.percentile(joints[plank][:, [20, 21, 10, 11], 1], 90) < 0.08
    # Lying down takes a person 2-3.5 s: from the pelvis starting down to the neck on the floor.
    for _, joints, _ in ground_truth["lie_down"]:
        start = np.argmax(joints[:, 0, 1] < joints[0, 0, 1] - 0.05)
        end = np.argmax(joints[:, 12, 1] < 0.2)
        assert 2.0 < (end - start) / SK.fps < 3.5, (end - start) / SK.fps


def test_feet_stay_planted_while_they_bear_weight(ground_truth):
    """Standing families: the lowest foot joint slides less than 3 mm a frame, on average."""
    feet = [7, 8, 10, 11]
    for family in ("pick_up", "touch_toes", "one_leg_stand", "point", "salute", "hands_on_hips",
                   "cross_arms", "nod", "march_in_place", "lunge"):
        for _, joints, _ in ground_truth[family]:
            low = joints[:, feet, 1].argmin(axis=1)
            planted = joints[np.arange(len(joints)), np.array(feet)[low]]
            slide = np.linalg.norm(np.diff(planted[:, [0, 2]], axis=0), axis=1)
            same = low[1:] == low[:-1]
            assert slide[same].mean() < 0.003, family


@pytest.mark.parametrize("family", NEW_FAMILIES)
def test_ground_truth_passes_its_checks(family, ground_truth):
    failed = [(p, c.name) for p, _, readings in ground_truth[family]
              for c in ro.checks_for({"family": family, "params": p})
              if not c(readings)]
    assert not failed, failed


@pytest.mark.parametrize("family", NEW_FAMILIES)
def test_other_families_fail_the_checks(family, others):
    """No motion of another family passes a new family's checks (each parameter combination)."""
    for params in _combos(family):
        passing = [(f, p) for f, p, r in others if f != family and _passes(r, family, params)]
        assert not passing, (family, params, passing)


def test_checks_tell_the_sides_and_counts_apart(ground_truth):
    wrong = {"pick_up": ("hand", {"left": "right", "right": "left", "both": "left"}),
             "one_leg_stand": ("leg", {"left": "right", "right": "left"}),
             "point": ("hand", {"left": "right", "right": "left"}),
             "salute": ("hand", {"left": "right", "right": "left"}),
             "jumping_jack": ("count", {2: 3, 3: 4, 4: 2}), "nod": ("count", {2: 3, 3: 2}),
             "push_up": ("count", {2: 3, 3: 4, 4: 2}), "lunge": ("leg", {"left": "right",
                                                                          "right": "left"})}
    for family, (key, other) in wrong.items():
        for params, _, readings in ground_truth[family]:
            assert not _passes(readings, family, dict(params, **{key: other[params[key]]})), \
                (family, params)


def test_a_squat_is_not_a_lie_down_and_lying_is_not_sitting(ground_truth):
    squat = ro.read_all(_motion("squat", {"count": 1}))
    assert not _passes(squat, "lie_down", {}) and not _passes(squat, "sit_floor", {})
    for _, _, readings in ground_truth["lie_down"]:
        assert not _passes(readings, "sit_floor", {})
    for _, _, readings in ground_truth["sit_floor"]:
        assert not _passes(readings, "lie_down", {})


def test_sequences_with_floor_transitions_pass_in_their_windows():
    for actions in ([("walk", {"speed": "normal", "direction": "forward"}), ("lie_down", {})],
                    [("lie_down", {}), ("get_up", {})],
                    [("get_up", {}), ("jumping_jack", {"count": 2})],
                    [("pick_up", {"hand": "left"}), ("sit_floor", {})]):
        script = Script(tuple(Action(f, p) for f, p in actions))
        rng = np.random.default_rng(3)
        composed = compose(script, RIG, Style(arm_length=RIG.arm_length,
                                              shoulder_x=RIG.shoulder_x), rng, SK.fps)
        joints = composed.positions / RIG.scale
        label = {"actions": [dict(a.to_json(), start=s / SK.fps, end=e / SK.fps)
                             for a, (s, e) in zip(script.actions, composed.segments)],
                 "frames": len(joints)}
        results = ro.evaluate_label(joints, label)
        assert all(ok for _, ok in results), (actions, [n for n, ok in results if not ok])


def test_version_three_scripts_follow_the_floor_and_keep_a_modest_share():
    rng = np.random.default_rng(0)
    scripts = [sample_script(rng, version=3) for _ in range(3000)]
    actions = [a for s in scripts for a in s.actions]
    share = np.mean([a.family in NEW_FAMILIES for a in actions])
    assert 0.2 < share < 0.4
    assert {a.family for a in actions} == set(FAMILIES_BY_VERSION[3])
    for script in scripts:
        families = [a.family for a in script.actions]
        for before, after in zip(families[:-1], families[1:]):
            if before in ENDS_DOWN:
                assert (before, after) == ("lie_down", "get_up"), families
            if after in STARTS_DOWN:
                assert before == "lie_down", families
    assert any(["lie_down", "get_up"] == [a.family for a in s.actions][:2] for s in scripts)


def test_the_command_makes_the_newest_version_and_the_functions_version_two(tmp_path):
    from mlct.cli import build_parser
    from mlct.data.synth.build import BENCHMARK_VERSION, DEFAULT_VERSION

    args = build_parser().parse_args(["data", "synth", "--out", str(tmp_path / "x")])
    assert args.benchmark_version == BENCHMARK_VERSION == 3 and DEFAULT_VERSION == 2
    assert make_motion(0, 0, SK).label == make_motion(0, 0, SK, version=2).label


def test_version_two_draws_only_its_families_as_before():
    rng = np.random.default_rng(0)
    families = {a.family for _ in range(2000) for a in sample_script(rng, version=2).actions}
    assert families == set(FAMILIES_BY_VERSION[2])
    # Motions 0-2 of seed 0, version 2, as the code before version 3 made them.
    known = ["sit_stand > turn(angle=45,side=left)",
             "wave(count=4,hand=left) > side_step(side=right,steps=4) > jog(direction=forward)",
             "walk_backward(speed=normal) + wave(count=4,hand=right)"]
    motions = [make_motion(i, 0, SK, version=2) for i in range(3)]
    assert [m.label["label"] for m in motions] == known
    # Their features' magnitude as that code wrote them (float32 files; float rounding aside).
    sums = [8514.452372480253, 15776.376115997004, 7504.906089779486]
    assert [float(np.abs(m.features.astype(np.float32).astype(np.float64)).sum())
            for m in motions] == pytest.approx(sums, rel=1e-7)
