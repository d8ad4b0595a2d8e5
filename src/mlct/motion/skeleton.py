"""Skeletons of the standard text-to-motion datasets (HumanML3D, KIT-ML).

Every constant that describes a skeleton lives here and nowhere else: joint names, parents and
kinematic chains, the raw offset directions used by the inverse kinematics of the standard
processing, the target skeleton's bone lengths, the foot / facing / leg joints, fps and the
feature layout. Facts follow EricGuo5513/HumanML3D (paramUtil.py, motion_representation).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class FeatureLayout:
    """Slices of the standard per-frame feature vector: 8 + (J-1)*9 + J*3 values."""

    n_joints: int

    @property
    def dim(self) -> int:
        return 8 + (self.n_joints - 1) * 9 + self.n_joints * 3

    @property
    def groups(self) -> dict[str, slice]:
        j = self.n_joints
        ric_end = 4 + (j - 1) * 3
        rot_end = ric_end + (j - 1) * 6
        vel_end = rot_end + j * 3
        return {
            "root_rot_velocity": slice(0, 1),  # angular velocity about y (half-angle, radians)
            "root_linear_velocity": slice(1, 3),  # xz velocity in the root frame
            "root_height": slice(3, 4),
            "ric": slice(4, ric_end),  # root-relative joint positions, facing +Z
            "rotations": slice(ric_end, rot_end),  # 6D joint rotations from IK
            "local_velocity": slice(rot_end, vel_end),  # joint velocities in the root frame
            "foot_contact": slice(vel_end, vel_end + 4),  # left 2, right 2
        }


@dataclass(frozen=True)
class Skeleton:
    """A skeleton: topology, offsets and the dataset conventions attached to it."""

    name: str
    joint_names: tuple[str, ...]
    kinematic_chain: tuple[tuple[int, ...], ...]
    # Unit bone directions of the standard processing's IK rest pose (paramUtil raw offsets).
    raw_offsets: np.ndarray
    # Bone lengths of the dataset's target skeleton (index = child joint; root = 0).
    bone_lengths: np.ndarray
    # Unit bone directions of a natural rest pose facing +Z with the body's left on +x
    # (right-handed, y up). Used to build motions by forward kinematics (synth, BVH).
    rest_directions: np.ndarray
    fps: float
    foot_left: tuple[int, int]  # ankle, toe
    foot_right: tuple[int, int]
    face_joints: tuple[int, int, int, int]  # right hip, left hip, right shoulder, left shoulder
    leg_joints: tuple[int, int]  # lower-leg joints whose offsets give the leg length (scale)
    contact_threshold: float  # squared per-frame foot displacement below which a foot is in contact
    min_frames: int  # dataset length filter (inclusive)
    max_frames: int  # exclusive upper bound of the standard filter (len < 200)
    unit: str = "m"
    parents: tuple[int, ...] = field(init=False)

    def __post_init__(self) -> None:
        parents = [-1] * len(self.joint_names)
        for chain in self.kinematic_chain:
            for parent, child in zip(chain[:-1], chain[1:]):
                parents[child] = parent
        object.__setattr__(self, "parents", tuple(parents))

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def layout(self) -> FeatureLayout:
        return FeatureLayout(self.n_joints)

    @property
    def feature_dim(self) -> int:
        return self.layout.dim

    @property
    def target_offsets(self) -> np.ndarray:
        """(J, 3) offsets of the target skeleton in the IK rest pose (raw direction * length)."""
        return self.raw_offsets * self.bone_lengths[:, None]

    @property
    def rest_offsets(self) -> np.ndarray:
        """(J, 3) offsets of the natural rest pose (facing +Z) with the target bone lengths."""
        return self.rest_directions * self.bone_lengths[:, None]

    def descendants(self, joint: int) -> tuple[int, ...]:
        """The joints that hang from `joint` (children, grandchildren, ...), in joint order."""
        found = {joint}
        for j in range(self.n_joints):  # parents come before their children in the order
            if self.parents[j] in found:
                found.add(j)
        return tuple(sorted(found - {joint}))

    def index(self, joint_name: str) -> int:
        try:
            return self.joint_names.index(joint_name)
        except ValueError:
            raise KeyError(f"skeleton {self.name!r} has no joint {joint_name!r}") from None


_T2M_RAW = np.array(
    [[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, -1, 0], [0, 1, 0], [0, -1, 0],
     [0, -1, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1], [0, 1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1],
     [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0]],
    dtype=np.float64,
)

# Bone lengths of HumanML3D's target skeleton (subject 000021, first frame), read off the
# distributed new_joints/012314.npy, whose bones all have these lengths (std < 1e-6 over frames).
_T2M_LENGTHS = np.array(
    [0.0, 0.103074, 0.109883, 0.131568, 0.393623, 0.390188, 0.143190, 0.432434, 0.425644,
     0.057365, 0.143382, 0.149419, 0.219360, 0.137487, 0.143383, 0.103039, 0.131614, 0.122984,
     0.256840, 0.263092, 0.266012, 0.269876],
    dtype=np.float64,
)

def _unit(rows: list[list[float]]) -> np.ndarray:
    vectors = np.array(rows, dtype=np.float64)
    norms = np.linalg.norm(vectors, axis=1, keepdims=True)
    return np.divide(vectors, norms, out=np.zeros_like(vectors), where=norms > 0)


# A standing pose facing +Z, left on +x, arms hanging: bone directions read off the SMPL
# template's joint layout (spine leaning slightly back then forward, collars up and out,
# feet pointing forward and down to the ball of the foot).
_T2M_REST = _unit([
    [0, 0, 0], [0.58, -0.81, 0.0], [-0.58, -0.81, 0.0], [0.0, 0.97, -0.24], [0.05, -1.0, 0.0],
    [-0.05, -1.0, 0.0], [0.0, 1.0, 0.05], [0.0, -1.0, -0.08], [0.0, -1.0, -0.08], [0.0, 0.9, 0.44],
    [0.12, -0.35, 0.93], [-0.12, -0.35, 0.93], [0.0, 0.99, -0.13], [0.53, 0.83, -0.15],
    [-0.53, 0.83, -0.15], [0.0, 0.8, 0.6], [0.93, 0.35, -0.08], [-0.93, 0.35, -0.08],
    [0.12, -0.99, 0.0], [-0.12, -0.99, 0.0], [0.05, -1.0, 0.1], [-0.05, -1.0, 0.1],
])

HUMANML3D = Skeleton(
    name="humanml3d",
    joint_names=(
        "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
        "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
        "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
        "left_wrist", "right_wrist",
    ),
    kinematic_chain=(
        (0, 2, 5, 8, 11), (0, 1, 4, 7, 10), (0, 3, 6, 9, 12, 15), (9, 14, 17, 19, 21),
        (9, 13, 16, 18, 20),
    ),
    raw_offsets=_T2M_RAW,
    bone_lengths=_T2M_LENGTHS,
    rest_directions=_T2M_REST,
    fps=20.0,
    foot_left=(7, 10),
    foot_right=(8, 11),
    face_joints=(2, 1, 17, 16),
    leg_joints=(5, 8),
    contact_threshold=0.002,
    min_frames=40,
    max_frames=200,
)

_KIT_RAW = np.array(
    [[0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, -1, 0], [0, -1, 0],
     [-1, 0, 0], [0, -1, 0], [0, -1, 0], [1, 0, 0], [0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, 1],
     [-1, 0, 0], [0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, 1]],
    dtype=np.float64,
)

# KIT-ML is in millimetres. The reference takes its target from subject 03950, which is not
# distributed with the code; these lengths are estimates for a 1.75 m MMM reference body.
# `uniform_skeleton(..., target_joints=...)` accepts the real subject's joints when available.
_KIT_LENGTHS = np.array(
    [0.0, 115.0, 205.0, 190.0, 150.0, 185.0, 285.0, 255.0, 185.0, 285.0, 255.0, 95.0, 430.0,
     420.0, 105.0, 60.0, 95.0, 430.0, 420.0, 105.0, 60.0],
    dtype=np.float64,
)

KIT = Skeleton(
    name="kit",
    joint_names=(
        "root", "pelvis", "torso", "neck", "head", "right_shoulder", "right_elbow",
        "right_wrist", "left_shoulder", "left_elbow", "left_wrist", "right_hip", "right_knee",
        "right_ankle", "right_metatarsal", "right_toe", "left_hip", "left_knee", "left_ankle",
        "left_metatarsal", "left_toe",
    ),
    kinematic_chain=((0, 11, 12, 13, 14, 15), (0, 16, 17, 18, 19, 20), (0, 1, 2, 3, 4),
                     (3, 5, 6, 7), (3, 8, 9, 10)),
    raw_offsets=_KIT_RAW,
    bone_lengths=_KIT_LENGTHS,
    # KIT's raw offsets put the right side on +x; mirror x for a rest pose facing +Z, and
    # point the feet forward and down from the ankle as a standing body's do.
    rest_directions=_unit([
        [0, 0, 0], [0, 1, 0], [0, 1, 0.05], [0, 1, 0], [0, 1, 0.1], [-1, 0, 0], [-0.1, -1, 0],
        [0, -1, 0.1], [1, 0, 0], [0.1, -1, 0], [0, -1, 0.1], [-1, -0.2, 0], [0, -1, 0],
        [0, -1, -0.05], [0, -0.55, 0.84], [0, -0.15, 1], [1, -0.2, 0], [0, -1, 0], [0, -1, -0.05],
        [0, -0.55, 0.84], [0, -0.15, 1],
    ]),
    fps=12.5,
    foot_left=(19, 20),
    foot_right=(14, 15),
    face_joints=(11, 16, 5, 8),
    leg_joints=(17, 18),
    contact_threshold=0.05,
    min_frames=24,
    max_frames=200,
    unit="mm",
)

SKELETONS: dict[str, Skeleton] = {"humanml3d": HUMANML3D, "kit": KIT}
_ALIASES = {"t2m": "humanml3d", "hml3d": "humanml3d", "humanml": "humanml3d", "kit-ml": "kit",
            "kitml": "kit"}


_UNITS_PER_METRE = {"m": 1.0, "mm": 1000.0}


def units_per_metre(skeleton: Skeleton) -> float:
    """How many of the skeleton's length units make a metre (1 for m, 1000 for mm)."""
    try:
        return _UNITS_PER_METRE[skeleton.unit]
    except KeyError:
        raise ValueError(f"skeleton {skeleton.name!r} has unknown unit {skeleton.unit!r}; "
                         f"known: {sorted(_UNITS_PER_METRE)}") from None


def get_skeleton(name: str) -> Skeleton:
    """The skeleton called `name` ('humanml3d' or 'kit'); an unknown name raises ValueError."""
    key = _ALIASES.get(name.lower(), name.lower())
    if key not in SKELETONS:
        raise ValueError(f"unknown skeleton {name!r}: choose one of {sorted(SKELETONS)}")
    return SKELETONS[key]


def skeleton_for_dim(feature_dim: int) -> Skeleton:
    """The skeleton whose standard feature vector has `feature_dim` values (263 or 251)."""
    for skeleton in SKELETONS.values():
        if skeleton.feature_dim == feature_dim:
            return skeleton
    dims = {s.name: s.feature_dim for s in SKELETONS.values()}
    raise ValueError(f"no skeleton has {feature_dim}-d features (known: {dims})")


def skeleton_for_joints(n_joints: int) -> Skeleton:
    """The skeleton with `n_joints` joints (22 or 21)."""
    for skeleton in SKELETONS.values():
        if skeleton.n_joints == n_joints:
            return skeleton
    raise ValueError(f"no skeleton has {n_joints} joints (known: 22 humanml3d, 21 kit)")
