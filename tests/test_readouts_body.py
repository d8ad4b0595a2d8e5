"""The whole-body families benchmark version 4 adds (synth/families_body.py): their motions are
physical, their read-outs pass their own ground truth and reject the other families' motions;
version 4 draws its families for a share of the actions and version 3 is remade as it was."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mlct.data.synth import families_body
from mlct.data.synth.actions import (ENDS_DOWN, FAMILIES, FAMILIES_BY_VERSION,
                                     VERSION_4_FAMILIES, Action, Script, sample_script)
from mlct.data.synth.build import VERSIONS, make_motion
from mlct.data.synth.compose import compose
from mlct.data.synth.motions import Style
from mlct.eval import readouts as ro
from mlct.eval.suites.ground_truth import RIG
from mlct.eval.suites.ground_truth import combos as _combos
from mlct.eval.suites.ground_truth import motion as _motion
from mlct.eval.suites.ground_truth import passes as _passes
from mlct.motion.skeleton import HUMANML3D as SK

BODY = tuple(families_body.PARAMS)
# Each family's first GROUND_TRUTH motions of bench/quality.py ground-truth's 300 (its parameter
# combinations in turn, styles drawn from the benchmark's range; that script measures all 300),
# and each parameter combination at the corners of the style range.
GROUND_TRUTH = 32
STYLE_CORNERS = tuple(itertools.product((0.85, 1.15), repeat=2))  # (amplitude, tempo)
PASS_RATE = 0.95  # of a family's own motions that pass its checks, at least


def test_version_three_is_remade_as_before_version_four():
    # Motions 0-5 of seed 0, version 3, as the code before version 4 made them.
    known = [("jumping_jack(count=2) > sit_floor", 10379.209627663251),
             ("nod(count=3)", 5239.936274501306),
             ("walk_backward(speed=normal) + wave(count=4,hand=right)", 7504.906089779486),
             ("kick(count=2,leg=left)", 5449.2322857757035), ("cross_arms", 7513.854610158838),
             ("hop(count=3,leg=left)", 6014.246677626566)]
    motions = [make_motion(i, 0, SK, version=3) for i in range(6)]
    assert [m.label["label"] for m in motions] == [label for label, _ in known]
    assert [float(np.abs(m.features.astype(np.float32).astype(np.float64)).sum())
            for m in motions] == pytest.approx([total for _, total in known], rel=1e-7)
    assert motions[1].lines[0].startswith("a figure nods three times.#")


def test_version_four_draws_its_families_for_a_share_of_the_actions():
    assert 4 in VERSIONS and FAMILIES_BY_VERSION[4] == FAMILIES
    assert set(FAMILIES_BY_VERSION[3]) | set(VERSION_4_FAMILIES) == set(FAMILIES)
    assert set(BODY) <= set(VERSION_4_FAMILIES)
    rng = np.random.default_rng(0)
    scripts = [sample_script(rng, version=4) for _ in range(3000)]
    actions = [a for s in scripts for a in s.actions]
    if VERSION_4_FAMILIES:
        share = np.mean([a.family in VERSION_4_FAMILIES for a in actions])
        assert 0.25 < share < 0.45
    assert {a.family for a in actions} == set(FAMILIES)
    for script in scripts:  # nothing follows a fall or any other floor ending but getting up
        families = [a.family for a in script.actions]
        for before, after in zip(families[:-1], families[1:]):
            if before in ENDS_DOWN:
                assert (before, after) == ("lie_down", "get_up"), families


@pytest.fixture(scope="module")
def ground_truth() -> dict[str, list[tuple[dict, np.ndarray, dict]]]:
    """GROUND_TRUTH motions of each body family, its parameter combinations in turn, then each
    combination at every corner of the style range, with their read-outs (made once)."""
    out = {}
    for family in BODY:
        combos = _combos(family)
        made = [(combos[k % len(combos)], _motion(family, combos[k % len(combos)], k))
                for k in range(GROUND_TRUTH)]
        made += [(params, _motion(family, params, 1000 + i, corner))
                 for params in combos for i, corner in enumerate(STYLE_CORNERS)]
        out[family] = [(params, joints, ro.read_all(joints)) for params, joints in made]
    return out


@pytest.fixture(scope="module")
def others() -> list[tuple[str, dict, dict]]:
    """The read-outs of two motions of every parameter combination (up to 6) of every family."""
    return [(f, p, ro.read_all(_motion(f, p, seed))) for f in FAMILIES for p in _combos(f)[:6]
            for seed in (11, 12)]


def test_body_motions_keep_bone_lengths(ground_truth):
    for family, motions in ground_truth.items():
        for _, joints, _ in motions:
            bones = np.linalg.norm(joints[:, 1:] - joints[:, list(SK.parents[1:])], axis=-1)
            assert np.abs(bones - SK.bone_lengths[1:]).max() < 1e-9, family


@pytest.mark.parametrize("family", BODY)
def test_ground_truth_passes_its_checks(family, ground_truth):
    passed = [_passes(r, family, p) for p, _, r in ground_truth[family]]
    assert np.mean(passed) >= PASS_RATE, (family, np.mean(passed))


@pytest.mark.parametrize("family", BODY)
def test_other_families_fail_the_checks(family, others):
    """No motion of another family passes a body family's checks (each parameter combination)."""
    for params in _combos(family):
        passing = [(f, p) for f, p, r in others if f != family and _passes(r, family, params)]
        assert not passing, (family, params, passing)


def test_stairs_put_each_foot_on_its_tread_and_the_script_goes_on_from_there(ground_truth):
    from mlct.data.synth.families_body import RISER, STAIR_STEPS

    for family, sign in (("walk_downstairs", -1), ("walk_upstairs", 1)):
        for _, joints, _ in ground_truth[family][:20] + ground_truth[family][GROUND_TRUTH:]:
            feet = joints[:, [7, 8, 10, 11], 1]
            assert feet.min(axis=1)[-1] == pytest.approx(sign * RISER * STAIR_STEPS, abs=0.03)
            # A toe still at a tread's level (a whole number of risers from where it
            # started) slides less than 5 mm a frame on average.
            for toe in (10, 11):
                level = (joints[:, toe, 1] - joints[0, toe, 1]) / RISER
                still = np.abs(level - np.round(level)) < 0.05
                still = still[1:] & still[:-1] & (np.abs(np.diff(joints[:, toe, 1])) < 0.002)
                still = np.convolve(still, np.ones(5), "same") == 5  # for a fifth of a second
                slide = np.linalg.norm(np.diff(joints[:, toe][:, [0, 2]], axis=0), axis=1)
                assert slide[still].mean() < 0.005, family
    # The dataset's features keep the flight of stairs (the root's height is absolute).
    import torch

    from mlct.motion.features import joints_to_features, recover_from_ric

    _, joints, _ = ground_truth["walk_downstairs"][0]
    features = joints_to_features(joints * RIG.scale, SK).features
    back = recover_from_ric(torch.from_numpy(features)).numpy()
    assert ro.read_all(back)["feet_level_change"] == pytest.approx(-RISER * STAIR_STEPS, abs=0.03)
    # A walk after the stairs walks on the lower floor.
    script = Script((Action("walk_downstairs", {}), Action("walk", {"speed": "normal",
                                                                    "direction": "forward"})))
    joints = compose(script, RIG, Style(arm_length=RIG.arm_length, shoulder_x=RIG.shoulder_x),
                     np.random.default_rng(3), SK.fps).positions / RIG.scale
    walking = joints[-40:, [7, 8, 10, 11], 1].min(axis=1)
    assert np.all(np.abs(walking + RISER * STAIR_STEPS) < 0.03)


def test_checks_tell_the_sides_and_counts_apart(ground_truth):
    wrong = {"step_over": ("leg", {"left": "right", "right": "left"}),
             "limp": ("side", {"left": "right", "right": "left"}),
             "sit_ups": ("count", {2: 3, 3: 4, 4: 2})}
    for family, (key, other) in wrong.items():
        if family not in ground_truth:
            continue
        passed = [_passes(r, family, dict(params, **{key: other[params[key]]}))
                  for params, _, r in ground_truth[family]]
        assert np.mean(passed) < 0.05, (family, np.mean(passed))


def test_falls_are_quick_and_lying_down_is_not_a_fall(ground_truth):
    for family in ("fall_forward", "fall_backward"):
        for _, _, readings in ground_truth[family]:
            assert readings["descent_time"] < 0.75
            assert not _passes(readings, "lie_down", {})
    for seed in range(10):
        assert not _passes(ro.read_all(_motion("lie_down", {}, seed)), "fall_backward", {})
