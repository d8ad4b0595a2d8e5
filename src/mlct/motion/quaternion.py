"""Quaternions [w, x, y, z] in torch: the one copy of rotation code in mlct.

All functions take (..., 4) quaternions (and (..., 3) vectors), broadcast over leading dims, keep
the dtype and device of their inputs and are differentiable. Rotations act as v' = q v q*, which
matches the matrices of `quat_to_matrix` (R v). numpy callers convert at the edges
(`torch.from_numpy(a)` on float64 arrays).
"""

from __future__ import annotations

import torch
from torch import Tensor


def _eps(x: Tensor) -> float:
    return float(torch.finfo(x.dtype).eps)


def qmul(q: Tensor, r: Tensor) -> Tensor:
    """Hamilton product q * r (apply r first, then q)."""
    w1, x1, y1, z1 = q.unbind(-1)
    w2, x2, y2, z2 = r.unbind(-1)
    return torch.stack(
        (
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ),
        dim=-1,
    )


def qinv(q: Tensor) -> Tensor:
    """Conjugate [w, -x, -y, -z]: the inverse of a unit quaternion."""
    # negated, not multiplied by a new tensor of signs: a CUDA graph cannot copy one from the
    # host (train/captured_step.py captures the autoencoder's joint loss)
    return torch.cat([q[..., :1], -q[..., 1:]], dim=-1)


def qnormalize(q: Tensor) -> Tensor:
    """Unit quaternion q / |q| (a zero quaternion stays zero instead of becoming NaN)."""
    return q / q.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(q.dtype).tiny)


def qrot(q: Tensor, v: Tensor) -> Tensor:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4); leading dims broadcast."""
    w, u = q[..., :1], q[..., 1:]
    u, v = torch.broadcast_tensors(u, v)
    uv = torch.cross(u, v, dim=-1)
    uuv = torch.cross(u, uv, dim=-1)
    return v + 2.0 * (w * uv + uuv)


def _any_perpendicular(u: Tensor) -> Tensor:
    """A unit vector perpendicular to u: u x e, e the basis axis least aligned with u."""
    e = torch.nn.functional.one_hot(u.abs().argmin(dim=-1), 3).to(u)
    p = torch.cross(u, e, dim=-1)
    return p / p.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(u.dtype).tiny)


def qbetween(u: Tensor, v: Tensor) -> Tensor:
    """The shortest rotation taking direction u (..., 3) to direction v; w >= 0.

    Built as normalize([|u||v| + u.v, u x v]) like the reference (half-way quaternion). Where u
    and v are opposite that is 0/0 (NaN in the reference); we return the 180 degree turn about an
    axis perpendicular to u instead.
    """
    u, v = torch.broadcast_tensors(u, v)
    uv_norm = (u.norm(dim=-1) * v.norm(dim=-1)).unsqueeze(-1)  # (..., 1)
    w = uv_norm + (u * v).sum(dim=-1, keepdim=True)
    q = torch.cat([w, torch.cross(u, v, dim=-1)], dim=-1)
    norm = q.norm(dim=-1, keepdim=True)
    # |q|^2 = 2|u||v| w, so |q| is ~sqrt(eps)|u||v| at machine-precision antiparallel vectors.
    opposite = norm <= 10.0 * _eps(q) * uv_norm
    turn = torch.cat([torch.zeros_like(w), _any_perpendicular(u)], dim=-1)
    return torch.where(opposite, turn, q / norm.clamp_min(torch.finfo(q.dtype).tiny))


def quat_from_axis_angle(axis: Tensor, angle: Tensor | float) -> Tensor:
    """Rotation by `angle` radians about `axis` (..., 3) (normalized here), right-handed."""
    axis = axis / axis.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(axis.dtype).tiny)
    half = torch.as_tensor(angle, dtype=axis.dtype, device=axis.device).unsqueeze(-1) / 2
    xyz = torch.sin(half) * axis  # (..., 3), leading dims of angle and axis broadcast
    return torch.cat([torch.cos(half).expand(xyz.shape[:-1] + (1,)), xyz], dim=-1)


def quat_to_matrix(q: Tensor) -> Tensor:
    """(..., 4) -> (..., 3, 3) rotation matrices; q need not be unit (scaled by 2/|q|^2)."""
    w, x, y, z = q.unbind(-1)
    s = 2.0 / (q * q).sum(dim=-1)
    m = torch.stack(
        (
            1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w),
            s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w),
            s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y),
        ),
        dim=-1,
    )
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(m: Tensor) -> Tensor:
    """(..., 3, 3) rotation matrices -> unit quaternions with w >= 0.

    Of the four textbook formulas (each divides by one quaternion component) we take the one whose
    divisor is largest, so the result is accurate and its gradient finite for every rotation.
    """
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4 * component^2 for w, x, y, z.
    sq = torch.stack(
        (1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22), dim=-1
    )
    two_c = sq.clamp_min(torch.finfo(m.dtype).tiny).sqrt()  # (..., 4): 2 |component|
    # Row k: 4 * component_k * q, i.e. the quaternion scaled by 2 * two_c[k].
    cands = torch.stack(
        (
            torch.stack((sq[..., 0], m21 - m12, m02 - m20, m10 - m01), dim=-1),
            torch.stack((m21 - m12, sq[..., 1], m10 + m01, m02 + m20), dim=-1),
            torch.stack((m02 - m20, m10 + m01, sq[..., 2], m12 + m21), dim=-1),
            torch.stack((m10 - m01, m20 + m02, m21 + m12, sq[..., 3]), dim=-1),
        ),
        dim=-2,
    ) / (2 * two_c[..., :, None])  # (..., 4, 4)
    best = torch.nn.functional.one_hot(sq.argmax(dim=-1), 4).to(m)  # (..., 4)
    q = (cands * best[..., :, None]).sum(dim=-2)
    return q * torch.where(q[..., :1] < 0, -1.0, 1.0).to(q)


def quat_to_rotvec(q: Tensor) -> Tensor:
    """(..., 4) -> (..., 3) rotation vectors (axis times angle, the angle in [0, pi]): the sign
    of q is taken so that w >= 0. A turn of angle a has |xyz| = sin(a / 2), w = cos(a / 2), so
    the vector is xyz * a / sin(a / 2); for a tiny turn that factor is 2 / w (its limit)."""
    q = q * torch.where(q[..., :1] < 0, -1.0, 1.0).to(q)
    w, xyz = q[..., :1], q[..., 1:]
    sin_half = xyz.norm(dim=-1, keepdim=True)
    tiny = sin_half < 1e3 * _eps(sin_half)
    angle = 2 * torch.atan2(sin_half, w)
    return xyz * torch.where(tiny, 2 / w, angle / torch.where(tiny, 1.0, sin_half))


def rotvec_to_matrix(rotvec: Tensor) -> Tensor:
    """(..., 3) rotation vectors (axis times angle) -> (..., 3, 3) rotation matrices."""
    return quat_to_matrix(quat_from_axis_angle(rotvec, rotvec.norm(dim=-1)))


def quat_to_cont6d(q: Tensor) -> Tensor:
    """(..., 4) -> (..., 6): the first two columns of the rotation matrix, column by column.

    This is the HumanML3D convention (quaternion_to_cont6d: cat(R[..., 0], R[..., 1])).
    """
    m = quat_to_matrix(q)
    return torch.cat([m[..., 0], m[..., 1]], dim=-1)


def cont6d_to_matrix(d6: Tensor) -> Tensor:
    """(..., 6) -> (..., 3, 3) columns by Gram-Schmidt: unit(a1), z cross x, unit(x cross a2)."""
    tiny = torch.finfo(d6.dtype).tiny
    a1, a2 = d6[..., :3], d6[..., 3:]
    x = a1 / a1.norm(dim=-1, keepdim=True).clamp_min(tiny)
    z = torch.cross(x, a2, dim=-1)
    z = z / z.norm(dim=-1, keepdim=True).clamp_min(tiny)
    y = torch.cross(z, x, dim=-1)
    return torch.stack([x, y, z], dim=-1)


def cont6d_to_quat(d6: Tensor) -> Tensor:
    """(..., 6) -> unit quaternions with w >= 0."""
    return matrix_to_quat(cont6d_to_matrix(d6))


def qslerp(q0: Tensor, q1: Tensor, t: Tensor | float) -> Tensor:
    """Spherical interpolation from q0 (t = 0) to q1 (t = 1) along the shorter arc.

    `t` is a float or a tensor broadcastable to the leading dims of q0 and q1.
    """
    q0, q1 = qnormalize(q0), qnormalize(q1)
    t = torch.as_tensor(t, dtype=q0.dtype, device=q0.device).unsqueeze(-1)
    dot = (q0 * q1).sum(dim=-1, keepdim=True)
    q1 = torch.where(dot < 0, -q1, q1)  # q and -q are the same rotation: take the short way
    dot = dot.abs()
    near = dot > 1 - 1e3 * _eps(dot)
    # Clamped so that the branch torch.where discards has a finite gradient.
    theta = torch.acos(dot.clamp(max=1 - 1e3 * _eps(dot)))
    sin_theta = torch.sin(theta)
    a = torch.where(near, 1 - t, torch.sin((1 - t) * theta) / sin_theta)
    b = torch.where(near, t, torch.sin(t * theta) / sin_theta)
    return qnormalize(a * q0 + b * q1)


def qfix(q: Tensor, dim: int = 0) -> Tensor:
    """Sign continuity along `dim` (time): flip q -> -q wherever consecutive frames disagree."""
    q = q.movedim(dim, 0)
    flip = (q[1:] * q[:-1]).sum(dim=-1, keepdim=True) < 0  # (T-1, ..., 1)
    sign = 1 - 2 * (torch.cumsum(flip.long(), dim=0) % 2)  # parity of flips so far
    out = torch.cat([q[:1], q[1:] * sign.to(q)], dim=0)
    return out.movedim(0, dim)
