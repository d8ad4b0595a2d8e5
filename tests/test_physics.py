"""Plausibility metrics on motions whose answers are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from dataset_factory import rest_pose

from mlct.motion.physics import (
    bone_length_variation,
    foot_skating_mask,
    foot_skating_ratio,
    ground_penetration,
    max_jerk,
    plausibility,
    units_per_metre,
)
from mlct.motion.skeleton import HUMANML3D, KIT

T = 41  # 40 frame pairs


def standing(skeleton=HUMANML3D, frames=T):
    """(T, J, 3) rest pose held still, in the skeleton's unit."""
    return np.repeat(rest_pose(skeleton)[None], frames, axis=0)


def drag_left_toe(joints, skeleton, speed_m_s, height_m=0.0):
    """Slide the left toe along +x at a constant speed, `height_m` above the floor."""
    joints = joints.copy()
    scale = units_per_metre(skeleton)
    toe = skeleton.foot_left[1]
    t = np.arange(joints.shape[0]) / skeleton.fps
    joints[:, toe, 0] = speed_m_s * t * scale
    joints[:, toe, 1] = height_m * scale
    return joints


def test_standing_still_does_not_skate():
    assert foot_skating_ratio(standing(), HUMANML3D) == 0.0
    assert foot_skating_mask(standing(), HUMANML3D).shape == (T - 1,)


@pytest.mark.parametrize("speed, skating_pairs", [
    (1.0, 40),  # every pair: even the zero-padded end windows average 0.6 m/s > 0.5
    (0.7, 38),  # first/last pair: window mean 3/5 * 0.7 = 0.42 < 0.5; next ones 4/5 * 0.7 = 0.56
    (0.55, 36),  # 4/5 * 0.55 = 0.44 < 0.5: two pairs at each end drop out
    (0.45, 0),  # below 0.5 m/s (2.25 cm per frame at 20 fps)
])
def test_dragged_toe_skates_at_known_rate(speed, skating_pairs):
    joints = drag_left_toe(standing(), HUMANML3D, speed)
    assert foot_skating_ratio(joints, HUMANML3D) == pytest.approx(skating_pairs / (T - 1))


def test_lifted_foot_does_not_skate():
    joints = drag_left_toe(standing(), HUMANML3D, 1.0, height_m=0.06)
    assert foot_skating_ratio(joints, HUMANML3D) == 0.0
    joints = drag_left_toe(standing(), HUMANML3D, 1.0, height_m=0.04)
    assert foot_skating_ratio(joints, HUMANML3D) == 1.0


def test_skating_only_in_contact_frames():
    joints = drag_left_toe(standing(), HUMANML3D, 1.0)
    joints[20:, HUMANML3D.foot_left[1], 1] = 0.2  # lifted from frame 20: pairs 0..18 in contact
    mask = foot_skating_mask(joints, HUMANML3D)
    assert mask[:19].all() and not mask[19:].any()


def test_kit_millimetres_and_fps_give_the_same_ratio():
    for speed, pairs in [(1.0, 40), (0.7, 38), (0.45, 0)]:
        joints = drag_left_toe(standing(KIT), KIT, speed)
        assert foot_skating_ratio(joints, KIT) == pytest.approx(pairs / (T - 1))
    # 40 mm above the floor is in contact (threshold 50 mm), 60 mm is not.
    assert foot_skating_ratio(drag_left_toe(standing(KIT), KIT, 1.0, 0.04), KIT) == 1.0
    assert foot_skating_ratio(drag_left_toe(standing(KIT), KIT, 1.0, 0.06), KIT) == 0.0


def test_fps_override_changes_the_speed():
    joints = drag_left_toe(standing(), HUMANML3D, 0.45)  # 2.25 cm per frame
    assert foot_skating_ratio(joints, HUMANML3D) == 0.0  # 0.45 m/s at 20 fps
    # 0.675 m/s at 30 fps; the end pairs' windows average 3/5 of it (0.405) and drop out.
    assert foot_skating_ratio(joints, HUMANML3D, fps=30.0) == pytest.approx(38 / 40)


def test_ground_penetration():
    joints = standing()
    assert ground_penetration(joints, HUMANML3D) == 0.0
    joints[7, 3, 1] = -0.03
    joints[9, 10, 1] = -0.01
    assert ground_penetration(joints, HUMANML3D) == pytest.approx(0.03)


def test_bone_length_variation():
    joints = standing() + np.linspace(0, 2, T)[:, None, None]  # rigid translation
    assert bone_length_variation(joints, HUMANML3D) == pytest.approx(0.0, abs=1e-12)
    # Stretch the left shin (knee 4 -> ankle 7) by 10 % in one frame (moving the foot along).
    stretched = joints.copy()
    shin = stretched[5, 7] - stretched[5, 4]
    stretched[5, [7, 10]] += 0.1 * shin
    mean = 1 + 0.1 / T  # mean length over the clip, in units of the rest length
    assert bone_length_variation(stretched, HUMANML3D) == pytest.approx(1.1 / mean - 1)


def test_max_jerk_of_a_cubic_is_exact():
    c = 3.0  # m/s^3
    t = np.arange(T) / HUMANML3D.fps
    joints = standing()
    joints[:, 0, 2] += c * t**3 / 6
    joints[:, 5] += np.array([2.0, 0.0, 0.0]) * t[:, None]  # constant velocity: no jerk
    assert max_jerk(joints, HUMANML3D) == pytest.approx(c)
    assert max_jerk(standing(), HUMANML3D) == 0.0
    assert max_jerk(standing(frames=3), HUMANML3D) == 0.0


def test_plausibility_and_shape_errors():
    metrics = plausibility(standing(), HUMANML3D)
    assert metrics == pytest.approx({"foot_skating_ratio": 0.0, "ground_penetration": 0.0,
                                     "bone_length_variation": 0.0, "max_jerk": 0.0})
    with pytest.raises(ValueError, match=r"\(T, 21, 3\)"):
        foot_skating_ratio(standing(), KIT)
    assert foot_skating_ratio(standing(frames=1), HUMANML3D) == 0.0
