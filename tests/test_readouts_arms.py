"""The arm, gesture and sports families benchmark version 4 adds (synth/families_arms.py): their
motions keep the body's bones and feet, their read-outs pass their own ground truth, reject the
other families' motions and tell the hands apart, and every vocabulary says them."""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest

from mlct.data.captions import pos_tag
from mlct.data.synth import families_arms
from mlct.data.synth.actions import FAMILIES, FAMILY_PARAMS, VERSION_4_FAMILIES, Action, Script
from mlct.data.synth.colloquial import COLLOQUIAL
from mlct.data.synth.compose import compose
from mlct.data.synth.everyday import EVERYDAY
from mlct.data.synth.motions import Style
from mlct.data.synth.short import SHORT
from mlct.data.synth.text import describe
from mlct.eval import readouts as ro
from mlct.eval.suites.ground_truth import RIG
from mlct.eval.suites.ground_truth import combos as _combos
from mlct.eval.suites.ground_truth import motion as _motion
from mlct.eval.suites.ground_truth import passes as _passes
from mlct.motion.skeleton import HUMANML3D as SK

ARMS = tuple(families_arms.PARAMS)
# Each family's first GROUND_TRUTH motions of bench/quality.py ground-truth's 300 (its parameter
# combinations in turn, styles drawn from the benchmark's range; that script measures all 300),
# and each parameter combination at the corners of the style range.
GROUND_TRUTH = 32
STYLE_CORNERS = tuple(itertools.product((0.85, 1.15), repeat=2))  # (amplitude, tempo)
PASS_RATE = 0.95  # of a family's own motions that pass its checks, at least


@pytest.fixture(scope="module")
def ground_truth() -> dict[str, list[tuple[dict, np.ndarray, dict]]]:
    """GROUND_TRUTH motions of each arm family, its parameter combinations in turn, then each
    combination at every corner of the style range, with their read-outs (made once)."""
    out = {}
    for family in ARMS:
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


def test_the_families_are_version_four_s():
    assert set(ARMS) <= set(VERSION_4_FAMILIES)
    assert set(families_arms.CLIPS) == set(ARMS) == set(ro.EXTRA_CHECKS) & set(ARMS)


def test_arm_motions_keep_bone_lengths_and_stand_on_the_floor(ground_truth):
    feet = [7, 8, 10, 11]
    for family, motions in ground_truth.items():
        for _, joints, _ in motions[:20] + motions[GROUND_TRUTH:]:  # and the style's corners
            bones = np.linalg.norm(joints[:, 1:] - joints[:, list(SK.parents[1:])], axis=-1)
            assert np.abs(bones - SK.bone_lengths[1:]).max() < 1e-9, family
            lowest = joints[..., 1].min(axis=1)
            assert lowest.min() > -1e-9 and np.percentile(lowest, 95) < 0.06, family
            # The planted foot slides under 3 mm a frame on average.
            low = joints[:, feet, 1].argmin(axis=1)
            planted = joints[np.arange(len(joints)), np.array(feet)[low]]
            slide = np.linalg.norm(np.diff(planted[:, [0, 2]], axis=0), axis=1)
            assert slide[low[1:] == low[:-1]].mean() < 0.003, family


def test_swings_are_as_fast_as_people_make_them(ground_truth):
    """The hand of a throw or a forehand moves at 6 m/s or more at its fastest, the club and the
    bat at 3.5 m/s or more; tai chi and looking around stay under 1 m/s."""
    least = {"throw": 6.0, "tennis_swing": 6.0, "golf_swing": 3.5, "bat_swing": 3.5}
    for family, speed in least.items():
        assert min(r["peak_wrist_speed"] for _, _, r in ground_truth[family]) > speed, family
    for family in ("tai_chi", "look_around", "sway"):
        assert max(r["peak_wrist_speed"] for _, _, r in ground_truth[family]) < 1.0, family


@pytest.mark.parametrize("family", ARMS)
def test_ground_truth_passes_its_checks(family, ground_truth):
    passed = [_passes(r, family, p) for p, _, r in ground_truth[family]]
    assert np.mean(passed) >= PASS_RATE, (family, np.mean(passed))


@pytest.mark.parametrize("family", ARMS)
def test_other_families_fail_the_checks(family, others):
    """No motion of another family passes an arm family's checks (each parameter combination)."""
    for params in _combos(family):
        passing = [(f, p) for f, p, r in others if f != family and _passes(r, family, params)]
        assert not passing, (family, params, passing)


@pytest.mark.parametrize("family", [f for f in ARMS if "hand" in FAMILY_PARAMS[f]])
def test_checks_tell_the_hands_apart(family, ground_truth):
    for params, _, readings in ground_truth[family]:
        other = "right" if params["hand"] == "left" else "left"
        assert not _passes(readings, family, dict(params, hand=other)), (family, params)


@pytest.mark.parametrize("family", ARMS)
def test_every_vocabulary_says_the_hand_and_only_it(family):
    for params in _combos(family):
        for vocabulary in (None, EVERYDAY, COLLOQUIAL, SHORT):
            kw = {} if vocabulary is None else {"vocabulary": vocabulary}
            caps = [c for s in range(12) for c in describe(
                [Action(family, params)], np.random.default_rng(s), **kw)]
            said = " | ".join(caps)
            if vocabulary is None:
                for caption in caps:
                    pos_tag(caption)  # every word in the lexicon
            assert not re.search(r"[<>]|\bHIS\b|\s,|\s\s|\ba [aeiou]", said), said
            hand = params.get("hand")
            if hand is None:
                continue
            other = "right" if hand == "left" else "left"
            assert not re.search(rf"\b{other}\b", said), (params, said)
            if vocabulary is not SHORT or hand == "left":  # short says the right hand bare
                assert all(re.search(rf"\b{hand}\b", c) for c in caps), (params, said)


@pytest.mark.parametrize("family", ARMS)
def test_arm_families_pass_in_their_windows_of_a_sequence(family):
    """After or before another action, each arm family's checks pass in its own window."""
    before = ("walk", {"speed": "normal", "direction": "forward"})
    after = ("turn", {"side": "left", "angle": 90})
    params = _combos(family)[-1]
    script = Script((Action(*before), Action(family, params), Action(*after)))
    composed = compose(script, RIG, Style(arm_length=RIG.arm_length, shoulder_x=RIG.shoulder_x),
                       np.random.default_rng(3), SK.fps)
    joints = composed.positions / RIG.scale
    label = {"actions": [dict(a.to_json(), start=s / SK.fps, end=e / SK.fps)
                         for a, (s, e) in zip(script.actions, composed.segments)],
             "frames": len(joints)}
    failed = [name for name, ok in ro.evaluate_label(joints, label) if not ok]
    assert not failed, (family, failed)
