"""Forward kinematics of a robot's body tree and a damped least-squares solver, in numpy,
vectorized over frames.

A chain is built from a table of bodies (g1.py: each with its parent, offset, fixed orientation
and one hinge about its own x, y or z). Its pose is a root position (T, 3), a root rotation
(T, 3, 3) and the hinge angles (T, n) in the table's joint order. Points are (body, offset in
the body's frame) pairs: the solver moves chosen joints (and, optionally, the root's position)
so that weighted points reach their targets, each step clamped to the joint limits.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of unit quaternions (..., 4) w, x, y, z."""
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions w, x, y, z (w >= 0) of rotation matrices (..., 3, 3)."""
    m = np.asarray(m, np.float64)
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    # four candidate forms; each frame takes the one with the largest (best conditioned) root
    cands = np.stack([
        np.stack([1 + trace, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                  m[..., 1, 0] - m[..., 0, 1]], -1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - trace,
                  m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0],
                  1 + 2 * m[..., 1, 1] - trace, m[..., 1, 2] + m[..., 2, 1]], -1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0],
                  m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - trace], -1),
    ], -2)
    norms = np.linalg.norm(cands, axis=-1)
    best = np.take_along_axis(cands, norms.argmax(-1)[..., None, None], axis=-2)[..., 0, :]
    q = best / np.linalg.norm(best, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations by angle (...) about the basis axis 0 (x), 1 (y) or 2 (z)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]  # the plane the hinge turns, in right-handed order
    m = np.zeros(np.shape(angle) + (3, 3))
    m[..., axis, axis] = 1.0
    m[..., i, i], m[..., j, j] = c, c
    m[..., i, j], m[..., j, i] = -s, s
    return m


@dataclass(frozen=True)
class Pose:
    """Forward kinematics of T frames: every body's world position (T, B, 3) and rotation
    (T, B, 3, 3)."""

    pos: np.ndarray
    rot: np.ndarray

    def point(self, body: int, offset: Sequence[float]) -> np.ndarray:
        """(T, 3): the world position of a point fixed in a body's frame."""
        return self.pos[:, body] + self.rot[:, body] @ np.asarray(offset, np.float64)


class Chain:
    """A body tree (a table of g1.Body-like rows, parents listed before children)."""

    def __init__(self, bodies: Sequence) -> None:
        names = [b.name for b in bodies]
        self.body_names = tuple(names)
        self.parents = tuple(-1 if b.parent is None else names.index(b.parent) for b in bodies)
        self.offsets = np.array([b.pos for b in bodies], np.float64)
        self.fixed = quat_to_matrix(np.array([b.quat for b in bodies], np.float64))
        jointed = [i for i, b in enumerate(bodies) if b.joint is not None]
        self.joint_body = tuple(jointed)  # joint k turns body joint_body[k]
        self.joint_names = tuple(bodies[i].joint for i in jointed)
        self.axes = tuple(bodies[i].axis for i in jointed)
        self.lower = np.array([bodies[i].lower for i in jointed])
        self.upper = np.array([bodies[i].upper for i in jointed])
        self._joint_of = {b: k for k, b in enumerate(jointed)}
        # ancestor[b, k]: joint k moves body b
        self.ancestor = np.zeros((len(bodies), len(jointed)), dtype=bool)
        for b in range(len(bodies)):
            a = b
            while a >= 0:
                if a in self._joint_of:
                    self.ancestor[b, self._joint_of[a]] = True
                a = self.parents[a]

    def body(self, name: str) -> int:
        return self.body_names.index(name)

    def joint(self, name: str) -> int:
        return self.joint_names.index(name)

    def clamp(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lower, self.upper)

    def forward(self, root_pos: np.ndarray, root_rot: np.ndarray, q: np.ndarray) -> Pose:
        """Every body's pose for a root (T, 3), (T, 3, 3) and joint angles (T, n)."""
        frames = len(q)
        pos = np.empty((frames, len(self.parents), 3))
        rot = np.empty((frames, len(self.parents), 3, 3))
        for b, parent in enumerate(self.parents):
            if parent < 0:
                pos[:, b], local = root_pos, root_rot @ self.fixed[b]
            else:
                pos[:, b] = pos[:, parent] + rot[:, parent] @ self.offsets[b]
                local = rot[:, parent] @ self.fixed[b]
            k = self._joint_of.get(b)
            rot[:, b] = local if k is None else local @ axis_rotation(self.axes[k], q[:, k])
        return Pose(pos, rot)

    def jacobian(self, pose: Pose, body: int, point: np.ndarray, joints: Sequence[int]
                 ) -> np.ndarray:
        """(T, 3, len(joints)): d point / d angle for a world point (T, 3) fixed to body: the
        hinge's world axis crossed with the lever from the hinge to the point."""
        out = np.zeros((len(point), 3, len(joints)))
        for column, k in enumerate(joints):
            if not self.ancestor[body, k]:
                continue
            b = self.joint_body[k]
            axis = pose.rot[:, b, :, self.axes[k]]
            out[:, :, column] = np.cross(axis, point - pose.pos[:, b])
        return out


@dataclass(frozen=True)
class Target:
    """A point of a body (offset in its frame) to bring to world positions (T, 3); weight
    scalar or per axis (3,)."""

    body: int
    offset: tuple[float, float, float]
    position: np.ndarray
    weight: float | tuple[float, float, float] = 1.0


def solve(chain: Chain, root_pos: np.ndarray, root_rot: np.ndarray, q: np.ndarray,
          joints: Sequence[int], targets: Sequence[Target], move_root: bool = False,
          iterations: int = 30, damping: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares (Levenberg-Marquardt style) over the given joints, and the root's
    position when move_root, every frame at once; each step is clamped to the joint limits.
    Returns the new (root_pos, q)."""
    q, root_pos = chain.clamp(np.array(q, np.float64)), np.array(root_pos, np.float64)
    joints = list(joints)
    n = len(joints) + (3 if move_root else 0)
    weights = np.concatenate([np.broadcast_to(np.sqrt(np.asarray(t.weight, float)), 3)
                              for t in targets])
    for _ in range(iterations):
        pose = chain.forward(root_pos, root_rot, q)
        rows, errors = [], []
        for t in targets:
            point = pose.point(t.body, t.offset)
            jac = chain.jacobian(pose, t.body, point, joints)
            if move_root:  # the root's translation moves every point one for one
                jac = np.concatenate([jac, np.broadcast_to(np.eye(3), (len(q), 3, 3))], -1)
            rows.append(jac)
            errors.append(t.position - point)
        jac = np.concatenate(rows, 1) * weights[:, None]
        err = np.concatenate(errors, 1) * weights
        jt = np.swapaxes(jac, 1, 2)
        step = np.linalg.solve(jt @ jac + damping ** 2 * np.eye(n), (jt @ err[..., None]))[..., 0]
        q[:, joints] = chain.clamp(q + _scatter(step[:, :len(joints)], joints, q.shape))[:, joints]
        if move_root:
            root_pos = root_pos + step[:, len(joints):]
    return root_pos, q


def _scatter(values: np.ndarray, joints: Sequence[int], shape: tuple[int, ...]) -> np.ndarray:
    out = np.zeros(shape)
    out[:, list(joints)] = values
    return out
