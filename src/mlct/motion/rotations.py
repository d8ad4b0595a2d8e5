"""Rotations in numpy for the rig exports (bvh.py, gltf.py, smpl.py, rigfit.py), which run
without torch: quaternion.py's formulas, term for term, on float arrays.

quaternion.py keeps the torch versions (differentiable, on any device: the features' IK and
the training losses); tests/test_motion_rotations.py holds the two to each other.
Quaternions are (..., 4) [w, x, y, z].
"""

from __future__ import annotations

import numpy as np


def _eps(x: np.ndarray) -> float:
    return float(np.finfo(x.dtype).eps)


def _tiny(x: np.ndarray) -> float:
    return float(np.finfo(x.dtype).tiny)


def _norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt((x * x).sum(axis=-1, keepdims=True))


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) -> (..., 3, 3) rotation matrices; q need not be unit (scaled by 2/|q|^2)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    s = 2.0 / (q * q).sum(axis=-1)
    m = np.stack((
        1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w),
        s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w),
        s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y),
    ), axis=-1)
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> unit quaternions with w >= 0 (the formula whose
    divisor is largest, as quaternion.matrix_to_quat)."""
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    sq = np.stack((1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                   1 - m00 - m11 + m22), axis=-1)  # 4 * component^2 for w, x, y, z
    two_c = np.sqrt(np.maximum(sq, _tiny(m)))
    cands = np.stack((
        np.stack((sq[..., 0], m21 - m12, m02 - m20, m10 - m01), axis=-1),
        np.stack((m21 - m12, sq[..., 1], m10 + m01, m02 + m20), axis=-1),
        np.stack((m02 - m20, m10 + m01, sq[..., 2], m12 + m21), axis=-1),
        np.stack((m10 - m01, m20 + m02, m21 + m12, sq[..., 3]), axis=-1),
    ), axis=-2) / (2 * two_c[..., :, None])  # (..., 4, 4)
    best = np.take_along_axis(cands, sq.argmax(axis=-1)[..., None, None], axis=-2)[..., 0, :]
    return best * np.where(best[..., :1] < 0, -1.0, 1.0).astype(best.dtype)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """(..., 4) -> (..., 3) rotation vectors (axis times angle, in [0, pi]; w >= 0 taken)."""
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0).astype(q.dtype)
    w, xyz = q[..., :1], q[..., 1:]
    sin_half = _norm(xyz)
    tiny = sin_half < 1e3 * _eps(sin_half)
    angle = 2 * np.arctan2(sin_half, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        return xyz * np.where(tiny, 2 / w, angle / np.where(tiny, 1.0, sin_half))


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Rotation by `angle` radians about `axis` (..., 3) (normalized here), right-handed."""
    axis = axis / np.maximum(_norm(axis), _tiny(axis))
    half = np.asarray(angle, dtype=axis.dtype)[..., None] / 2
    xyz = np.sin(half) * axis
    return np.concatenate([np.broadcast_to(np.cos(half), xyz.shape[:-1] + (1,)), xyz], axis=-1)


def rotvec_to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors (axis times angle) -> (..., 3, 3) rotation matrices."""
    return quat_to_matrix(quat_from_axis_angle(rotvec, _norm(rotvec)[..., 0]))


def qbetween(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The shortest rotation taking direction u (..., 3) to direction v, w >= 0; opposite
    directions give the half turn about an axis perpendicular to u (quaternion.qbetween)."""
    u, v = np.broadcast_arrays(u, v)
    uv_norm = _norm(u) * _norm(v)  # (..., 1)
    w = uv_norm + (u * v).sum(axis=-1, keepdims=True)
    q = np.concatenate([w, np.cross(u, v)], axis=-1)
    norm = _norm(q)
    opposite = norm <= 10.0 * _eps(q) * uv_norm
    e = np.eye(3, dtype=u.dtype)[np.abs(u).argmin(axis=-1)]
    p = np.cross(u, e)
    p = p / np.maximum(_norm(p), _tiny(u))
    turn = np.concatenate([np.zeros_like(w), p], axis=-1)
    return np.where(opposite, turn, q / np.maximum(norm, _tiny(q)))
