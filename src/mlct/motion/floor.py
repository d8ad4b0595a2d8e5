"""A level floor under a captured clip: the tilt of the floor the feet stand on, and the rotation
that takes it out.

Why: a capture volume's floor is not always the horizontal plane of its coordinates. In CMU's
AMC walks of subjects 7 and 8 the lowest foot rises 7-10 cm over a 4 m walk (about 1.5
degrees): the feet are on the floor all along, the floor is tilted. Placed by its lowest joint,
such a clip starts with its feet on y = 0 and ends with both of them 10 cm up, so a walk reads as
one in flight and a model trained on it learns to float.

The floor is found where the body stands: in every half-overlapping second of the clip, the
lowest foot joint (ankles and toes) at its lowest frame. A plane is fitted to those support
points along each horizontal direction the clip travels at least MIN_EXTENT m (a walk along a
line tells nothing about the tilt across it), once more without the points it misses by more
than OUTLIER m. Only a small tilt is taken for the volume's error: a steeper one (stairs, a
ramp, a climb, uneven ground) is the motion's own and is left as captured.

Joints are (T, J, 3), y up, in the skeleton's unit (thresholds are in metres and scaled).
"""

from __future__ import annotations

import numpy as np

from mlct.motion.rotations import qbetween, quat_to_matrix
from mlct.motion.skeleton import Skeleton, units_per_metre

MIN_EXTENT = 1.5  # m of travel along a direction before its tilt is read
MAX_TILT = np.radians(4.0)  # a steeper floor is taken for the terrain (stairs rise ~30 deg)
OUTLIER = 0.03  # m: support points this far off the first plane are not floor (a foot up)
WINDOW_SECONDS = 1.0  # one support point per second: every gait stands in that time


def support_points(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(N, 3): the lowest foot joint at its lowest frame of each half-overlapping second."""
    feet = np.array(list(skeleton.foot_left) + list(skeleton.foot_right))
    heights = positions[:, feet, 1]  # (T, 4)
    lowest = feet[heights.argmin(axis=1)]  # (T,) joint index of the lowest foot joint
    lowest_height = heights.min(axis=1)
    window = max(2, round(WINDOW_SECONDS * skeleton.fps))
    points = []
    for start in range(0, max(1, len(positions) - window // 2), window // 2):
        frame = start + int(lowest_height[start:start + window].argmin())
        points.append(positions[frame, lowest[frame]])
    return np.asarray(points)


def floor_gradient(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray | None:
    """(2,) the floor's rise per unit of x and of z, from the support points; None when the clip
    does not travel MIN_EXTENT m in any direction or the fitted floor is steeper than MAX_TILT."""
    return _gradient_of(support_points(positions, skeleton), skeleton)


def _gradient_of(points: np.ndarray, skeleton: Skeleton) -> np.ndarray | None:
    if len(points) < 4:
        return None
    ground = points[:, [0, 2]] - points[:, [0, 2]].mean(axis=0)
    # principal directions of the travel; only those with enough extent are fitted
    _, _, axes = np.linalg.svd(ground, full_matrices=False)
    along = ground @ axes.T  # (N, 2)
    use = np.ptp(along, axis=0) >= MIN_EXTENT * units_per_metre(skeleton)
    if not use.any():
        return None
    design = np.column_stack([along[:, use], np.ones(len(points))])
    keep = np.ones(len(points), dtype=bool)
    for _ in range(2):  # fit, drop the points the plane misses by more than OUTLIER, refit
        coef, *_ = np.linalg.lstsq(design[keep], points[keep, 1], rcond=None)
        keep = np.abs(points[:, 1] - design @ coef) <= OUTLIER * units_per_metre(skeleton)
        if keep.sum() < 4:
            return None
    slopes = np.zeros(2)
    slopes[use] = coef[:-1]
    gradient = axes.T @ slopes  # back to (x, z)
    if np.arctan(np.linalg.norm(gradient)) > MAX_TILT:
        return None
    return gradient


def level_floor(positions: np.ndarray, skeleton: Skeleton) -> tuple[np.ndarray, float]:
    """(positions turned so that the floor under them is horizontal, the tilt removed in
    radians). The turn takes the floor's normal to +y, about the clip's mean support point; a
    clip whose tilt cannot be read (see `floor_gradient`) comes back unchanged, tilt 0."""
    points = support_points(positions, skeleton)
    gradient = _gradient_of(points, skeleton)
    if gradient is None or not np.any(gradient):
        return positions, 0.0
    normal = np.array([-gradient[0], 1.0, -gradient[1]])
    turn = quat_to_matrix(qbetween(normal, np.array([0.0, 1.0, 0.0])))
    centre = points.mean(axis=0)
    return (positions - centre) @ turn.T + centre, float(np.arctan(np.linalg.norm(gradient)))
