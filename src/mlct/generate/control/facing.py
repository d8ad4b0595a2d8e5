"""Where a pose faces: its heading about the vertical, which chains (compose/long_motion.py),
gaits that keep going and controls (controlled.py, fit.py) all turn motions by."""

from __future__ import annotations

import numpy as np

from mlct.motion.skeleton import Skeleton


def heading(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(..., J, 3) -> (...,) facing angle about +y, 0 when facing +Z (atan2 of forward x, z)."""
    r_hip, l_hip, r_shoulder, l_shoulder = skeleton.face_joints
    across = (joints[..., r_hip, :] - joints[..., l_hip, :]
              + joints[..., r_shoulder, :] - joints[..., l_shoulder, :])
    forward_x, forward_z = across[..., 2], -across[..., 0]  # forward = y x across
    return np.arctan2(forward_x, forward_z)
