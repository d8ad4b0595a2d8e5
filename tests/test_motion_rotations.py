"""motion/rotations.py (numpy, the rig exports') against motion/quaternion.py (torch)."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.motion import rotations

torch = pytest.importorskip("torch")
from mlct.motion import quaternion  # noqa: E402 - after the skip

RNG = np.random.default_rng(0)
QUATS = RNG.normal(size=(64, 4))
QUATS[:4] = [[1, 0, 0, 0], [0, 1, 0, 0], [-1, 1e-12, 0, 0], [0, 0, 0, -1]]  # edge cases
VECS = RNG.normal(size=(64, 3))


def _same(numpy_out: np.ndarray, torch_out: torch.Tensor, tol: float = 1e-12) -> None:
    assert numpy_out.shape == tuple(torch_out.shape)
    assert np.abs(numpy_out - torch_out.numpy()).max() < tol


def test_quaternions_and_matrices():
    q = torch.from_numpy(QUATS)
    _same(rotations.quat_to_matrix(QUATS), quaternion.quat_to_matrix(q))
    matrices = quaternion.quat_to_matrix(q)
    _same(rotations.matrix_to_quat(matrices.numpy()), quaternion.matrix_to_quat(matrices))
    _same(rotations.quat_to_rotvec(QUATS), quaternion.quat_to_rotvec(q))


def test_rotation_vectors_and_shortest_turns():
    v = torch.from_numpy(VECS)
    _same(rotations.rotvec_to_matrix(VECS), quaternion.rotvec_to_matrix(v))
    _same(rotations.rotvec_to_matrix(np.zeros((2, 3))), quaternion.rotvec_to_matrix(
        torch.zeros(2, 3, dtype=torch.float64)))
    u = np.concatenate([VECS[:8], VECS[:8]])
    w = np.concatenate([VECS[8:16], -VECS[:8]])  # the second half opposite
    _same(rotations.qbetween(u, w), quaternion.qbetween(torch.from_numpy(u),
                                                        torch.from_numpy(w)))
