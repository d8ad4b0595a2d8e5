"""One body-part table for edits and the arm pair, on both skeletons."""

import pytest

from mlct.errors import MlctError
from mlct.motion.body_parts import PARTS, joint_index, part_joints
from mlct.motion.skeleton import skeleton_for_dim

HML = skeleton_for_dim(263)
KIT = skeleton_for_dim(251)


def _names(joints, skeleton):
    return {skeleton.joint_names[j] for j in joints}


def test_arms_are_collar_or_shoulder_down_to_wrist():
    assert _names(part_joints("arms", HML), HML) == {
        f"{side}_{j}" for side in ("left", "right")
        for j in ("collar", "shoulder", "elbow", "wrist")}
    # KIT has no collars: its arms hang from the shoulders
    assert _names(part_joints("arms", KIT), KIT) == {
        f"{side}_{j}" for side in ("left", "right") for j in ("shoulder", "elbow", "wrist")}
    assert _names(part_joints("left_arm", KIT), KIT) == {"left_shoulder", "left_elbow",
                                                          "left_wrist"}


def test_every_part_exists_on_both_skeletons_and_upper_lower_split_the_body():
    # outside both halves: the root, and KIT's pelvis joint between the root and the torso
    for skeleton, neither in ((HML, {"pelvis"}), (KIT, {"root", "pelvis"})):
        for part in PARTS:
            assert part_joints(part, skeleton)
        upper, lower = set(part_joints("upper", skeleton)), set(part_joints("lower", skeleton))
        assert not upper & lower
        assert _names(set(range(skeleton.n_joints)) - upper - lower, skeleton) == neither
        assert _names(part_joints("head", skeleton), skeleton) >= {"neck", "head"}


def test_joint_names_mix_with_parts_and_bad_names_say_so():
    assert part_joints(["left_wrist", "head"], HML) == tuple(sorted(
        {HML.joint_names.index("left_wrist"), *part_joints("head", HML)}))
    assert joint_index(3, HML) == 3
    with pytest.raises(MlctError, match="unknown part 'tail'"):
        part_joints("tail", KIT)
    with pytest.raises(MlctError, match="not one of the 21 joints"):
        joint_index(30, KIT)
