"""Planted feet (motion/foot_lock.py) on hand-built legs, and in the pipeline."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.motion.foot_lock import (FootLock, contact_slide, contact_spans, correction,
                                   lock_feet, two_bone_ik)
from mlct.motion.skeleton import HUMANML3D

SKELETON = HUMANML3D


@pytest.fixture(scope="module")
def bundled():
    import mlct

    return mlct.load()
FPS = SKELETON.fps
L_ANKLE, L_TOE = SKELETON.foot_left
R_ANKLE, R_TOE = SKELETON.foot_right


def standing(frames: int, skeleton=SKELETON) -> np.ndarray:
    """(frames, J, 3) the rest pose on the floor (lowest joint at y = 0), the body 6 cm lower
    on knees bent forward, so that a foot may move 10 cm and still be reached."""
    offsets = skeleton.rest_offsets
    unit = 1000.0 if skeleton.unit == "mm" else 1.0
    pose = np.zeros((skeleton.n_joints, 3))
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            pose[joint] = pose[parent] + offsets[joint]
    feet = (*skeleton.foot_left, *skeleton.foot_right)
    knees = [skeleton.parents[skeleton.foot_left[0]], skeleton.parents[skeleton.foot_right[0]]]
    upper = [j for j in range(skeleton.n_joints) if j not in (*knees, *feet)]
    pose[upper, 1] -= 0.06 * unit
    pose[knees, 1] -= 0.03 * unit
    pose[knees, 2] += 0.08 * unit
    pose[:, 1] -= pose[:, 1].min()
    return np.repeat(pose[None], frames, axis=0)


def sliding_left_foot(frames: int = 40, speed: float = 0.15) -> np.ndarray:
    """Standing, the left foot (ankle and toe) sliding forward at `speed` m/s on the floor for
    frames 10-29 and lifted 10 cm off it elsewhere: one contact span."""
    joints = standing(frames)
    drift = np.clip(np.arange(frames) - 10, 0, 19) * speed / FPS
    joints[:, [L_ANKLE, L_TOE], 2] += drift[:, None]
    lifted = (np.arange(frames) < 10) | (np.arange(frames) >= 30)
    joints[np.ix_(lifted, [L_ANKLE, L_TOE], [1])] += 0.10
    return joints


def test_a_sliding_foot_on_the_floor_is_one_contact_span() -> None:
    joints = sliding_left_foot()
    assert contact_spans(joints, SKELETON, L_TOE, FootLock()) == [(10, 30)]
    # a foot sliding faster than a standing foot does is swinging, not standing
    assert contact_spans(sliding_left_foot(speed=1.2), SKELETON, L_TOE, FootLock()) == []
    # the right foot stands still throughout
    assert contact_spans(joints, SKELETON, R_TOE, FootLock()) == [(0, 40)]
    # slow, but 0.4 m in all (20 cm from where it stands on average): a step, not a slide
    assert contact_spans(sliding_left_foot(speed=0.6), SKELETON, L_TOE, FootLock()) == []
    assert contact_spans(sliding_left_foot(speed=0.6), SKELETON, L_TOE,
                         FootLock(max_hold=0.3)) == [(10, 30)]


def test_the_planted_foot_holds_its_mean_position_and_the_legs_keep_their_lengths() -> None:
    joints = sliding_left_foot()
    locked = lock_feet(joints, SKELETON)
    toe = locked[10:30, L_TOE]
    # held: the toe does not move over the span, at the mean of where it slid
    assert np.abs(toe - toe[0]).max() < 1e-9
    assert toe[0, 2] == pytest.approx(joints[10:30, L_TOE, 2].mean(), abs=1e-9)
    assert toe[0, 1] == pytest.approx(joints[10, L_TOE, 1])  # heights are not changed
    # thigh and shin keep their lengths in every frame; the foot moves as one piece
    knee, hip = SKELETON.parents[L_ANKLE], SKELETON.parents[SKELETON.parents[L_ANKLE]]
    for a, b in ((hip, knee), (knee, L_ANKLE), (L_ANKLE, L_TOE)):
        np.testing.assert_allclose(np.linalg.norm(locked[:, a] - locked[:, b], axis=-1),
                                   np.linalg.norm(joints[:, a] - joints[:, b], axis=-1),
                                   atol=1e-9)
    # the rest of the body does not move; the right foot stood still and stays
    moved = {L_ANKLE, L_TOE, knee}
    others = [j for j in range(SKELETON.n_joints) if j not in moved]
    np.testing.assert_allclose(locked[:, others], joints[:, others], atol=1e-12)


def test_the_correction_fades_in_and_out_around_a_span() -> None:
    toe_xz = np.zeros((40, 2))
    toe_xz[10:30, 1] = np.arange(20) * 0.015  # slides 0.3 m/s
    offset = correction(toe_xz, [(10, 30)], blend=3)
    assert np.all(offset[:6] == 0) and np.all(offset[34:] == 0)  # untouched beyond the blend
    assert 0 < abs(offset[8, 1]) < abs(offset[9, 1]) < abs(offset[10, 1])  # fades in
    assert 0 < abs(offset[31, 1]) < abs(offset[30, 1]) < abs(offset[29, 1])  # and out
    # a short lift between two spans: one offset turns into the next, never through zero
    two = correction(toe_xz, [(10, 18), (21, 30)], blend=3)
    assert np.all(np.abs(two[18:21, 1]) > 0)


def test_two_bone_ik_reaches_what_it_can_and_stops_short_of_straight() -> None:
    hip = np.array([[0.0, 1.0, 0.0]])
    knee = np.array([[0.0, 0.55, 0.05]])
    ankle = np.array([[0.0, 0.1, 0.0]])
    target = np.array([[0.0, 0.15, 0.2]])
    new_knee, new_ankle = two_bone_ik(hip, knee, ankle, target)
    np.testing.assert_allclose(new_ankle, target, atol=1e-9)
    assert np.linalg.norm(new_knee - hip) == pytest.approx(np.linalg.norm(knee - hip))
    assert np.linalg.norm(new_ankle - new_knee) == pytest.approx(np.linalg.norm(ankle - knee))
    assert new_knee[0, 2] > 0.1  # bent forward, as it was
    # out of reach: the leg points at the target, 0.1 % short of straight
    far_knee, far_ankle = two_bone_ik(hip, knee, ankle, np.array([[0.0, 1.0, 2.0]]))
    legs = np.linalg.norm(knee - hip) + np.linalg.norm(ankle - knee)
    assert np.linalg.norm(far_ankle - hip) == pytest.approx(0.999 * legs)
    assert far_ankle[0, 1] == pytest.approx(1.0) and far_ankle[0, 2] > 0


def test_a_motion_without_contacts_and_bad_shapes() -> None:
    jump = standing(20)
    jump[:, :, 1] += 0.3  # in the air throughout: nothing to hold
    np.testing.assert_array_equal(lock_feet(jump, SKELETON), jump)
    with pytest.raises(ValueError, match="expected joints of shape"):
        lock_feet(np.zeros((10, 21, 3)), SKELETON)


def _in_contact_slide(joints: np.ndarray) -> float:
    return contact_slide(joints, SKELETON)


def test_the_pipeline_plants_the_feet_of_a_walk(bundled) -> None:
    planted = bundled.generate("a person walks forward", seconds=4, seed=0)[0]
    bundled.foot_lock = None
    try:
        as_decoded = bundled.generate("a person walks forward", seconds=4, seed=0)[0]
    finally:
        bundled.foot_lock = FootLock()
    # the decoded walk slides its standing feet (the data's do too); planted, they stand
    assert _in_contact_slide(as_decoded.joints) > 0.03
    assert _in_contact_slide(planted.joints) < 0.005
    # the body above the knees is the same motion
    knees = [SKELETON.parents[L_ANKLE], SKELETON.parents[R_ANKLE]]
    upper = [j for j in range(SKELETON.n_joints) if j not in (L_ANKLE, L_TOE, R_ANKLE, R_TOE,
                                                              *knees)]
    np.testing.assert_allclose(planted.joints[:, upper], as_decoded.joints[:, upper], atol=1e-6)
    assert np.abs(planted.joints - as_decoded.joints).max() > 0.01
    # the features follow the planted joints (derived when read), one row per frame
    assert planted.features.shape == as_decoded.features.shape
    from mlct.motion.features import recover_from_ric
    import torch

    # (HumanML3D's processing puts the motion on its standard bone lengths, which moves the
    # feet a little: 0.11 -> 0.02 m/s here, against 0.000 for the planted joints themselves)
    again = recover_from_ric(torch.from_numpy(planted.features)).numpy()
    assert _in_contact_slide(again) < _in_contact_slide(as_decoded.joints) / 3


def test_the_cli_plants_feet_unless_told_not_to(tmp_path) -> None:
    from mlct.cli import main

    for name, flags in (("on.npy", []), ("off.npy", ["--no-plant-feet"])):
        assert main(["generate", "a person walks forward", "--seconds", "4", "--seed", "0",
                     "--backend", "torch", "--out", str(tmp_path / name), *flags]) == 0
    on, off = np.load(tmp_path / "on.npy"), np.load(tmp_path / "off.npy")
    assert on.shape == off.shape == (80, 22, 3)
    assert _in_contact_slide(on) < 0.005 < 0.03 < _in_contact_slide(off)


def test_foot_contacts_label_each_foot_frame_by_frame() -> None:
    from mlct.motion.foot_lock import foot_contacts

    contacts = foot_contacts(sliding_left_foot(), SKELETON)
    assert contacts.shape == (40, 2) and contacts.dtype == bool
    assert contacts[:, 1].all()  # the right foot stands throughout
    np.testing.assert_array_equal(np.flatnonzero(contacts[:, 0]), np.arange(10, 30))
    # a slow step that strays too far to be held is still a foot on the floor
    assert foot_contacts(sliding_left_foot(speed=0.6), SKELETON)[10:30, 0].all()
    # in the air: no contact
    jump = standing(20)
    jump[:, :, 1] += 0.3
    assert not foot_contacts(jump, SKELETON).any()


def test_the_motion_json_carries_the_contacts_of_a_walk(bundled) -> None:
    from mlct.generate.output.exports import motion_json

    record = motion_json(bundled.generate("a person walks forward", seconds=4, seed=0)[0])
    contacts = np.asarray(record["foot_contacts"], dtype=bool)
    assert contacts.shape == (80, 2)
    one_foot = contacts[:, 0] != contacts[:, 1]
    # the feet take turns: long stretches on one foot, each foot down 30-80 % of the time
    assert one_foot.mean() > 0.5 and np.all((contacts.mean(0) > 0.3) & (contacts.mean(0) < 0.8))
    swaps = np.flatnonzero(np.diff(contacts[one_foot, 0].astype(int)))
    assert len(swaps) >= 4


def test_the_bvh_of_a_planted_walk_keeps_its_feet_planted(bundled, tmp_path) -> None:
    """The rig fit (fixed bone lengths, fitted rotations) must not bring the slide back."""
    from mlct.motion.bvh import read_bvh

    walk = bundled.generate("a person walks forward", seconds=5, seed=0)[0]
    walk.save(tmp_path / "walk.bvh")
    clip = read_bvh(tmp_path / "walk.bvh")
    joints = clip.positions[:, [clip.joint_names.index(n) for n in SKELETON.joint_names]] / 100
    assert _in_contact_slide(joints) < 0.02  # decoded, it slides ~0.1 m/s


def test_a_kit_motion_in_millimetres_at_its_own_frame_rate() -> None:
    from mlct.motion.skeleton import KIT

    metatarsal, toe = KIT.foot_left  # KIT's foot pair; its ankle is the metatarsal's parent
    ankle = KIT.parents[metatarsal]
    joints = standing(30, KIT)
    joints[:, [ankle, metatarsal, toe], 2] += np.arange(30)[:, None] * 0.04 / KIT.fps * 1000
    assert contact_spans(joints, KIT, toe, FootLock()) == [(0, 30)]  # 0.04 m/s, in mm
    locked = lock_feet(joints, KIT)
    ground = locked[:, toe][:, [0, 2]]
    assert np.abs(ground - ground[0]).max() < 1.0  # held to within a millimetre
    knee, hip = KIT.parents[ankle], KIT.parents[KIT.parents[ankle]]
    for a, b in ((hip, knee), (knee, ankle)):  # thigh and shin kept their lengths
        np.testing.assert_allclose(np.linalg.norm(locked[:, a] - locked[:, b], axis=-1),
                                   np.linalg.norm(joints[:, a] - joints[:, b], axis=-1),
                                   rtol=1e-9)
    # where this near-straight leg could not reach, the heel rose (at most 3 cm) and the toe
    # stayed down: the foot's length changes a little there
    lift = locked[:, ankle, 1] - joints[:, ankle, 1]
    assert lift.max() > 0 and lift.max() <= 30.0 + 1e-6
    np.testing.assert_allclose(locked[:, toe, 1], joints[:, toe, 1], atol=1e-9)
    foot = [np.linalg.norm(j[:, metatarsal] - j[:, ankle], axis=-1) for j in (locked, joints)]
    assert np.all(np.abs(foot[0] - foot[1]) <= np.abs(lift) + 1e-6)  # by no more than the rise
    assert np.abs(locked[:, hip] - joints[:, hip]).max() == 0  # the hip does not move


def test_a_motion_on_a_path_is_planted_one_with_keyframes_is_not(bundled) -> None:
    path = {"path": [[0.0, 0.0, 0], [0.0, 1.5, 40], [1.0, 2.5, 79]]}
    planted = bundled.generate("a person walks forward", seconds=4, seed=0, control=path)[0]
    bundled.foot_lock = None
    try:
        decoded = bundled.generate("a person walks forward", seconds=4, seed=0,
                                   control=path)[0]
    finally:
        bundled.foot_lock = FootLock()
    # planted: the feet stand (a walk on a path is the text's walk re-timed to it, whose feet
    # the correction already holds where the walk stood them: planting has little left to do)
    assert _in_contact_slide(planted.joints) < 0.005
    assert _in_contact_slide(planted.joints) <= _in_contact_slide(decoded.joints)
    np.testing.assert_array_equal(planted.joints[:, 0], decoded.joints[:, 0])  # the same path
    # a keyframe pins joints where it puts them: left as the control made it
    pose = decoded.joints[40].tolist()
    keyed = {"keyframes": [{"frame": 40, "pose": pose}]}
    first = bundled.generate("a person walks forward", seconds=4, seed=0, control=keyed)[0]
    bundled.foot_lock = None
    try:
        second = bundled.generate("a person walks forward", seconds=4, seed=0, control=keyed)[0]
    finally:
        bundled.foot_lock = FootLock()
    np.testing.assert_array_equal(first.joints, second.joints)


def test_planting_adds_no_flight_to_a_walk(bundled) -> None:
    """A stance leg is near straight: a hold it cannot reach must not lift the whole foot (it
    did once, and a 9.5-s stroll got frames with both feet 2 cm up: a walk's flight)."""
    from mlct.eval.readouts import flight_frames

    for seed in (0, 3):
        planted = bundled.generate("a man strolls down the street", seconds=9.5, seed=seed)[0]
        bundled.foot_lock = None
        try:
            decoded = bundled.generate("a man strolls down the street", seconds=9.5,
                                       seed=seed)[0]
        finally:
            bundled.foot_lock = FootLock()
        assert flight_frames(planted.joints) <= flight_frames(decoded.joints)
        assert _in_contact_slide(planted.joints) < _in_contact_slide(decoded.joints) / 2


def test_a_joints_descendants() -> None:
    from mlct.motion.skeleton import KIT

    assert SKELETON.descendants(L_ANKLE) == (L_TOE,)
    assert SKELETON.descendants(SKELETON.parents[L_ANKLE]) == (L_ANKLE, L_TOE)
    assert KIT.descendants(KIT.parents[KIT.foot_left[0]]) == KIT.foot_left  # ankle: the foot
    assert SKELETON.descendants(L_TOE) == ()
