"""Quaternion identities against closed forms."""

import math

import pytest
import torch

from mlct.motion.quaternion import (
    cont6d_to_matrix, cont6d_to_quat, matrix_to_quat, qbetween, qfix, qinv, qmul, qnormalize, qrot,
    qslerp, quat_from_axis_angle, quat_to_cont6d, quat_to_matrix,
)

F64 = torch.float64


def random_quats(n: int, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return qnormalize(torch.randn(n, 4, generator=g, dtype=F64))


def rot_y(angle: float) -> torch.Tensor:
    c, s = math.cos(angle), math.sin(angle)
    return torch.tensor([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=F64)


def canonical(q: torch.Tensor) -> torch.Tensor:
    return torch.where(q[..., :1] < 0, -q, q)


@pytest.mark.parametrize("angle", [0.0, 0.3, -1.2, math.pi / 2, 3.0])
def test_rotation_about_y_matches_closed_form(angle):
    q = quat_from_axis_angle(torch.tensor([0.0, 2.0, 0.0], dtype=F64), angle)
    expected = torch.tensor([math.cos(angle / 2), 0, math.sin(angle / 2), 0], dtype=F64)
    torch.testing.assert_close(q, expected)
    torch.testing.assert_close(quat_to_matrix(q), rot_y(angle))
    # +Z turns towards +X for a positive angle about +y (right-handed).
    torch.testing.assert_close(qrot(q, torch.tensor([0.0, 0.0, 1.0], dtype=F64)),
                               torch.tensor([math.sin(angle), 0.0, math.cos(angle)], dtype=F64))


def test_qmul_composes_like_matrices_and_qinv_inverts():
    q, r = random_quats(64, 1), random_quats(64, 2)
    torch.testing.assert_close(quat_to_matrix(qmul(q, r)), quat_to_matrix(q) @ quat_to_matrix(r))
    identity = torch.tensor([1.0, 0, 0, 0], dtype=F64).expand(64, 4)
    torch.testing.assert_close(qmul(q, qinv(q)), identity)
    y = torch.tensor([0.0, 1.0, 0.0], dtype=F64)
    torch.testing.assert_close(qmul(quat_from_axis_angle(y, 0.4), quat_from_axis_angle(y, 0.9)),
                               quat_from_axis_angle(y, 1.3))


def test_qrot_matches_matrix_and_broadcasts():
    q = random_quats(32)
    v = torch.randn(32, 3, dtype=F64)
    torch.testing.assert_close(qrot(q, v), (quat_to_matrix(q) @ v[..., None])[..., 0])
    # One quaternion applied to many vectors; lengths are preserved.
    many = torch.randn(5, 7, 3, dtype=F64)
    out = qrot(q[0], many)
    assert out.shape == (5, 7, 3)
    torch.testing.assert_close(out.norm(dim=-1), many.norm(dim=-1))


def test_qbetween_known_cases_and_random():
    x, y, z = torch.eye(3, dtype=F64)
    h = math.sqrt(0.5)
    # x to y: 90 degrees about z.
    torch.testing.assert_close(qbetween(x, y), torch.tensor([h, 0, 0, h], dtype=F64))
    torch.testing.assert_close(qbetween(3 * z, z), torch.tensor([1.0, 0, 0, 0], dtype=F64))
    u, v = torch.randn(100, 3, dtype=F64), torch.randn(100, 3, dtype=F64)
    q = qbetween(u, v)
    assert (q[:, 0] >= 0).all()
    torch.testing.assert_close(q.norm(dim=-1), torch.ones(100, dtype=F64))
    unit_u, unit_v = u / u.norm(dim=-1, keepdim=True), v / v.norm(dim=-1, keepdim=True)
    torch.testing.assert_close(qrot(q, unit_u), unit_v)
    # Opposite directions: a finite 180 degree turn (the reference gives NaN here).
    for a in (z, -y, torch.tensor([1.0, 2.0, -0.5], dtype=F64)):
        q = qbetween(-a, a)
        assert torch.isfinite(q).all()
        torch.testing.assert_close(qrot(q, -a), a)
    # The turn from -Z to +Z is a yaw (about y), as the facing normalization needs.
    torch.testing.assert_close(qbetween(-z, z)[[1, 3]], torch.zeros(2, dtype=F64))


def test_matrix_round_trips_including_half_turns():
    q = torch.cat([random_quats(200), quat_from_axis_angle(torch.randn(4, 3, dtype=F64), math.pi),
                   quat_from_axis_angle(torch.randn(4, 3, dtype=F64), math.pi - 1e-7),
                   torch.tensor([[1.0, 0, 0, 0]], dtype=F64)])
    torch.testing.assert_close(matrix_to_quat(quat_to_matrix(q)), canonical(q))
    m = quat_to_matrix(q)
    torch.testing.assert_close(quat_to_matrix(matrix_to_quat(m)), m)
    assert (matrix_to_quat(m)[:, 0] >= 0).all()


def test_cont6d_is_first_two_columns_and_round_trips():
    angle = 0.7
    d6 = quat_to_cont6d(quat_from_axis_angle(torch.tensor([0.0, 1.0, 0.0], dtype=F64), angle))
    c, s = math.cos(angle), math.sin(angle)
    torch.testing.assert_close(d6, torch.tensor([c, 0, -s, 0, 1, 0], dtype=F64))
    q = random_quats(100)
    torch.testing.assert_close(cont6d_to_matrix(quat_to_cont6d(q)), quat_to_matrix(q))
    torch.testing.assert_close(cont6d_to_quat(quat_to_cont6d(q)), canonical(q))
    # Any (non-degenerate) 6D input maps to a proper rotation.
    m = cont6d_to_matrix(torch.randn(50, 6, dtype=F64))
    torch.testing.assert_close(m.transpose(-1, -2) @ m, torch.eye(3, dtype=F64).expand(50, 3, 3))
    torch.testing.assert_close(torch.linalg.det(m), torch.ones(50, dtype=F64))


def test_qslerp_endpoints_midpoint_and_short_way():
    y = torch.tensor([0.0, 1.0, 0.0], dtype=F64)
    q0, q1 = quat_from_axis_angle(y, 0.2), quat_from_axis_angle(y, 1.4)
    torch.testing.assert_close(qslerp(q0, q1, 0.0), q0)
    torch.testing.assert_close(qslerp(q0, q1, 1.0), q1)
    torch.testing.assert_close(qslerp(q0, q1, 0.5), quat_from_axis_angle(y, 0.8))
    torch.testing.assert_close(qslerp(q0, -q1, 0.25), quat_from_axis_angle(y, 0.5))  # -q1 == q1
    t = torch.linspace(0, 1, 5, dtype=F64)
    out = qslerp(q0, q1, t)  # a tensor of times gives one quaternion per time
    torch.testing.assert_close(out, quat_from_axis_angle(y, 0.2 + 1.2 * t))
    torch.testing.assert_close(qslerp(q0, q0, 0.3), q0)  # identical ends: no NaN


def test_qfix_restores_sign_continuity():
    y = torch.tensor([0.0, 1.0, 0.0], dtype=F64)
    smooth = quat_from_axis_angle(y, torch.linspace(0, 5, 40, dtype=F64))[:, None].repeat(1, 3, 1)
    g = torch.Generator().manual_seed(0)
    signs = torch.where(torch.rand(40, 3, 1, generator=g) < 0.5, -1.0, 1.0).to(F64)
    signs[0] = 1.0
    torch.testing.assert_close(qfix(smooth * signs), smooth)
    # Time on another axis.
    flipped = (smooth * signs).transpose(0, 1)
    torch.testing.assert_close(qfix(flipped, dim=1), smooth.transpose(0, 1))


def test_dtype_preserved_and_gradients_finite():
    q = random_quats(8).float()
    v = torch.randn(8, 3)
    for out in (qmul(q, q), qrot(q, v), qbetween(v, -v), quat_to_cont6d(q),
                matrix_to_quat(quat_to_matrix(q)), qslerp(q, q.flip(0), 0.3)):
        assert out.dtype == torch.float32
    u = torch.randn(6, 3, dtype=F64, requires_grad=True)
    w = torch.randn(6, 3, dtype=F64, requires_grad=True)
    assert torch.autograd.gradcheck(qbetween, (u, w))
    m = quat_to_matrix(random_quats(6)).requires_grad_(True)
    assert torch.autograd.gradcheck(matrix_to_quat, (m,))
    d6 = torch.randn(6, 6, dtype=F64, requires_grad=True)
    assert torch.autograd.gradcheck(cont6d_to_matrix, (d6,))
    a, b = random_quats(6, 3).requires_grad_(True), random_quats(6, 4).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x, y: qslerp(x, y, 0.3), (a, b))


def test_rotation_vectors_are_scipys():
    """quat_to_rotvec and rotvec_to_matrix (the SMPL writer's and reader's, without scipy's
    import) against scipy's Rotation: random turns, half turns, tiny and zero ones."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from mlct.motion.quaternion import matrix_to_quat, quat_to_rotvec, rotvec_to_matrix

    turns = Rotation.random(1000, random_state=1)
    rotvec = np.concatenate([turns.as_rotvec(), [[0.0, 0.0, 0.0], [1e-12, -2e-12, 0.0],
                                                 [math.pi, 0.0, 0.0], [0.0, 0.0, -math.pi + 1e-9]]])
    matrices = Rotation.from_rotvec(rotvec).as_matrix()
    np.testing.assert_allclose(rotvec_to_matrix(torch.from_numpy(rotvec)).numpy(), matrices,
                               atol=1e-12)
    back = quat_to_rotvec(matrix_to_quat(torch.from_numpy(matrices))).numpy()
    expect = Rotation.from_matrix(matrices).as_rotvec()
    near_half_turn = np.linalg.norm(expect, axis=-1) > math.pi - 1e-6  # v and -v: one turn
    np.testing.assert_allclose(back[~near_half_turn], expect[~near_half_turn], atol=1e-9)
    np.testing.assert_allclose(rotvec_to_matrix(torch.from_numpy(back)).numpy(), matrices,
                               atol=1e-9)
    w_negative = -matrix_to_quat(torch.from_numpy(matrices[:10]))  # the same turns
    np.testing.assert_allclose(quat_to_rotvec(w_negative).numpy(), back[:10], atol=1e-12)
