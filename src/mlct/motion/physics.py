"""Physical plausibility of joint-position motions: foot skating, ground penetration, bone
length drift, jerk.

Joints are (T, J, 3) arrays in the skeleton's convention: y up, the floor at y = 0 (the standard
processing puts the lowest joint of the clip on the floor), lengths in the skeleton's unit (m for
HumanML3D, mm for KIT-ML). Thresholds are given in metres and seconds and scaled to the unit, so
one definition serves both skeletons. Results are in the skeleton's unit.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

# units_per_metre lives with the skeleton (whose module needs no scipy); importable from here
from mlct.motion.skeleton import Skeleton, units_per_metre  # noqa: F401


def _check_joints(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """`joints` as a float64 (T, J, 3) array with the skeleton's joint count."""
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (skeleton.n_joints, 3):
        raise ValueError(f"expected joints of shape (T, {skeleton.n_joints}, 3) for "
                         f"{skeleton.name}, got {joints.shape}")
    return joints


def foot_skating_mask(joints: np.ndarray, skeleton: Skeleton, *, fps: float | None = None,
                      height: float = 0.05, speed: float = 0.5, window: int = 5,
                      foot_joints: tuple[int, ...] | None = None) -> np.ndarray:
    """(T-1,) bool: frame pairs where a foot skates (GMD's definition, see foot_skating_ratio)."""
    joints = _check_joints(joints, skeleton)
    fps = skeleton.fps if fps is None else fps
    if foot_joints is None:
        foot_joints = (skeleton.foot_left[1], skeleton.foot_right[1])  # the toes, as GMD
    scale = units_per_metre(skeleton)
    if joints.shape[0] < 2:
        return np.zeros(0, dtype=bool)
    feet = joints[:, list(foot_joints)]  # (T, F, 3)
    # Horizontal (xz) speed between consecutive frames, in metres per second.
    step = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1)  # (T-1, F)
    velocity = step * fps / scale
    # Moving average over `window` frame pairs, zero-padded at the ends (scipy mode='constant'),
    # exactly as the reference: the first and last pairs see a diluted average.
    velocity_avg = uniform_filter1d(velocity, size=window, axis=0, mode="constant", cval=0.0)
    low = feet[..., 1] / scale < height  # (T, F)
    contact = low[:-1] & low[1:]  # on the ground in both frames of the pair
    skating = contact & (velocity > speed) & (velocity_avg > speed)  # (T-1, F)
    return skating.any(axis=1)


def foot_skating_ratio(joints: np.ndarray, skeleton: Skeleton, *, fps: float | None = None,
                       height: float = 0.05, speed: float = 0.5, window: int = 5,
                       foot_joints: tuple[int, ...] | None = None) -> float:
    """Fraction of frame pairs in which a foot skates (GMD, Karunratanakul et al. 2023).

    The definition of GMD's `calculate_skating_ratio`, also used by OmniControl: a foot joint
    (the toes: SMPL joints 10 and 11 on HumanML3D) skates between frames t and t+1 when it is
    below `height` (0.05 m) in both frames and its horizontal speed exceeds `speed` (0.5 m/s,
    i.e. 2.5 cm per frame at 20 fps) both in that pair and on average over a centred window of
    `window` (5) pairs. A pair counts when either foot skates; the ratio is over the T-1 pairs.
    GMD hard-codes 20 fps; we use the skeleton's fps (12.5 for KIT-ML) and scale the lengths by
    its unit (mm for KIT-ML). Pass `foot_joints` to count other joints (e.g. ankles too).
    """
    mask = foot_skating_mask(joints, skeleton, fps=fps, height=height, speed=speed,
                             window=window, foot_joints=foot_joints)
    return float(mask.mean()) if mask.size else 0.0


def ground_penetration(joints: np.ndarray, skeleton: Skeleton) -> float:
    """Deepest point of any joint below the floor (y = 0), in the skeleton's unit; 0 if none."""
    joints = _check_joints(joints, skeleton)
    if joints.size == 0:
        return 0.0
    return float(max(0.0, -joints[..., 1].min()))


def bone_lengths_over_time(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, J-1) length of each bone (parent -> child, children in joint order) per frame."""
    joints = _check_joints(joints, skeleton)
    children = [j for j, p in enumerate(skeleton.parents) if p >= 0]
    parents = [skeleton.parents[j] for j in children]
    return np.linalg.norm(joints[:, children] - joints[:, parents], axis=-1)


def bone_length_variation(joints: np.ndarray, skeleton: Skeleton) -> float:
    """Largest relative deviation of a bone's length from its mean over the clip.

    max over bones b and frames t of |L_b(t) / mean_t L_b - 1|: 0 for a rigid skeleton, 0.1 when
    some bone is 10 % off its mean length in some frame. Bones of zero mean length are ignored.
    """
    lengths = bone_lengths_over_time(joints, skeleton)  # (T, B)
    if lengths.size == 0:
        return 0.0
    mean = lengths.mean(axis=0)
    # A bone whose ends coincide throughout has no length to be relative to.
    valid = mean > 1e-9 * units_per_metre(skeleton)
    if not valid.any():
        return 0.0
    return float(np.abs(lengths[:, valid] / mean[valid] - 1.0).max())


def max_jerk(joints: np.ndarray, skeleton: Skeleton, *, fps: float | None = None) -> float:
    """Largest jerk magnitude |d^3 x / dt^3| of any joint, in the skeleton's unit per s^3.

    Third finite difference x[t+3] - 3 x[t+2] + 3 x[t+1] - x[t], times fps^3: exact for cubic
    trajectories. 0 for clips shorter than 4 frames.
    """
    joints = _check_joints(joints, skeleton)
    fps = skeleton.fps if fps is None else fps
    if joints.shape[0] < 4:
        return 0.0
    jerk = np.diff(joints, n=3, axis=0) * fps**3  # (T-3, J, 3)
    return float(np.linalg.norm(jerk, axis=-1).max())


def plausibility(joints: np.ndarray, skeleton: Skeleton,
                 fps: float | None = None) -> dict[str, float]:
    """All metrics of this module for one clip, by name."""
    return {
        "foot_skating_ratio": foot_skating_ratio(joints, skeleton, fps=fps),
        "ground_penetration": ground_penetration(joints, skeleton),
        "bone_length_variation": bone_length_variation(joints, skeleton),
        "max_jerk": max_jerk(joints, skeleton, fps=fps),
    }
