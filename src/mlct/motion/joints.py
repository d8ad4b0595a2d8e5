"""Features -> joints in numpy: the inverse of the root and ric groups (features.py), for
inference, rendering and the exports, which run without torch.

features.recover_from_ric computes the same in torch, differentiably, on the device of its input
(the autoencoder's joint loss); this is its float64 numpy twin, tested against it
(tests/test_motion_joints.py).
"""

from __future__ import annotations

import numpy as np

from mlct.errors import MlctError


def n_joints_for_dim(feature_dim: int) -> int:
    """Number of joints J of a D = 12 J - 1 dimensional feature vector (263 -> 22, 251 -> 21)."""
    if feature_dim < 11 or (feature_dim + 1) % 12:
        raise MlctError(f"{feature_dim} is not a standard feature width (12 * joints - 1)")
    return (feature_dim + 1) // 12


def _qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4) (quaternion.qrot)."""
    w, u = q[..., :1], q[..., 1:]
    u, v = np.broadcast_arrays(u, v)
    uv = np.cross(u, v)
    return v + 2.0 * (w * uv + np.cross(u, uv))


def root_yaw_and_position(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(..., T, D) -> the inverse root yaw quaternions (..., T, 4), root to world, and the root
    positions (..., T, 3) (features.recover_root_rot_pos, whose rotation this inverts)."""
    rot_vel = features[..., 0]
    half = np.concatenate([np.zeros_like(rot_vel[..., :1]),
                           np.cumsum(rot_vel[..., :-1], axis=-1)], axis=-1)  # (..., T)
    zero = np.zeros_like(half)
    to_world = np.stack([np.cos(half), zero, -np.sin(half), zero], axis=-1)  # qinv(r_rot)
    vel = features[..., :-1, 1:3]  # (..., T-1, 2) in the root frame of the later frame
    vel = np.stack([vel[..., 0], np.zeros_like(vel[..., 0]), vel[..., 1]], axis=-1)
    vel = np.concatenate([np.zeros(vel.shape[:-2] + (1, 3)), vel], axis=-2)  # (..., T, 3)
    xz = np.cumsum(_qrot(to_world, vel), axis=-2)
    return to_world, np.stack([xz[..., 0], features[..., 3], xz[..., 2]], axis=-1)


def features_to_joints(features: np.ndarray, n_joints: int | None = None) -> np.ndarray:
    """(..., T, D) features -> (..., T, J, 3) global joint positions, computed in float64 and
    returned in the features' float dtype (float32 for others)."""
    features = np.asarray(features)
    dtype = features.dtype if features.dtype.kind == "f" else np.dtype(np.float32)
    f = features.astype(np.float64)
    n_joints = n_joints_for_dim(f.shape[-1]) if n_joints is None else n_joints
    to_world, root = root_yaw_and_position(f)
    ric = f[..., 4:4 + (n_joints - 1) * 3]
    ric = ric.reshape(ric.shape[:-1] + (n_joints - 1, 3))  # (..., T, J-1, 3)
    world = _qrot(to_world[..., None, :], ric)
    world[..., 0] += root[..., None, 0]  # the root's x, z
    world[..., 2] += root[..., None, 2]
    return np.concatenate([root[..., None, :], world], axis=-2).astype(dtype)
