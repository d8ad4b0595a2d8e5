"""ReadingGaps names the read-outs a reconstruction loses: a march whose knees stay down shows
its foot lift as the largest gap; a perfect reconstruction shows none."""

from __future__ import annotations

import numpy as np
from test_readouts_more import _combos, _motion

from mlct.eval.suites.reading_gaps import ReadingGaps
from mlct.motion.skeleton import HUMANML3D

MARCH = {"actions": [{"family": "march_in_place", "params": {}}]}


def _knees_kept_down(joints: np.ndarray) -> np.ndarray:
    """The motion with each knee, ankle and foot held at its first frame's height: the body
    and arms move as they did, only the lift is gone (what the autoencoder does to a march)."""
    out = joints.copy()
    legs = [HUMANML3D.joint_names.index(f"{side}_{part}") for side in ("left", "right")
            for part in ("knee", "ankle", "foot")]
    out[:, legs, 1] = joints[:1, legs, 1]
    return out


def test_a_march_without_its_knee_lift_names_the_foot_lift():
    gaps = ReadingGaps()
    for family in ("stand", "walk", "jump", "wave", "squat"):  # what the spreads are made of
        other = _motion(family, _combos(family)[0])
        gaps.add({"actions": [{"family": family, "params": {}}]}, other, other)
    truth = _motion("march_in_place", {})
    gaps.add(MARCH, truth, _knees_kept_down(truth))
    top = gaps.largest("march_in_place", top=8)
    names = [key for key, _, _ in top]
    # every gap named is the legs' lift (the arms and the pelvis moved as they did)
    assert all(key.startswith(("foot_", "ankle_", "high_step", "knee_")) for key in names), names
    lift = next((t, m) for key, t, m in top if key.startswith("foot_lift"))
    assert lift[0] > 0.15 and lift[1] < 0.05, lift


def test_a_perfect_reconstruction_has_no_gap_and_sequences_are_left_out():
    gaps = ReadingGaps()
    truth = _motion("march_in_place", {})
    gaps.add(MARCH, truth, truth)
    assert all(t == m for _, t, m in gaps.largest("march_in_place"))
    two = {"actions": [{"family": "walk", "params": {}}, {"family": "stand", "params": {}}]}
    gaps.add(two, truth, truth[:10])
    assert gaps.largest("walk") == []
