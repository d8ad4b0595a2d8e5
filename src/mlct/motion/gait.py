"""Steps: how often the lower foot changes side, on any skeleton. One owner for the read-outs'
foot_swaps (eval/readouts.py) and keep-going's test of a gait (generate/compose/keep_going.py);
the cadence bench/control.py reports (steps_per_second)."""

from __future__ import annotations

import numpy as np

from mlct.motion.skeleton import Skeleton


def foot_swaps(joints: np.ndarray, skeleton: Skeleton, hysteresis: float = 0.03) -> int:
    """(T, J, 3) -> how often the lower foot (its ankle or toe, whichever is lower) changes
    side; a change counts once the other foot is lower by more than `hysteresis` m, so two
    feet planted side by side do not flicker."""
    joints = np.asarray(joints)
    left = joints[:, list(skeleton.foot_left), 1].min(axis=1)
    right = joints[:, list(skeleton.foot_right), 1].min(axis=1)
    swaps, lower = 0, 0  # -1: the left foot is the lower, 1: the right, 0: not yet known
    for d in left - right:
        now = -1 if d < -hysteresis else 1 if d > hysteresis else lower
        swaps += lower != 0 and now != lower
        lower = now
    return int(swaps)


def steps_per_second(joints: np.ndarray, skeleton: Skeleton, fps: float | None = None) -> float:
    """Cadence: foot_swaps per second of the motion (its T - 1 frame steps); a fast step whose
    foot stands too briefly for a contact span still changes the lower foot."""
    fps = skeleton.fps if fps is None else fps
    seconds = (len(joints) - 1) / fps
    return foot_swaps(joints, skeleton) / seconds if seconds > 0 else 0.0
