"""Closed-form checks of the schedule, consistency parameterization, solver and quantizer."""

from __future__ import annotations

import math

import pytest
import torch

from mlct.diffusion.consistency import (
    c_out,
    c_skip,
    consistency_output,
    guided_target,
    pseudo_huber,
)
from mlct.diffusion.schedule import VPSchedule, karras_time_grid, sampling_times
from mlct.diffusion.solver import ddim_step, dpm_solver_1_step
from mlct.nn.quantize import quantize

F64 = torch.float64


def _t(*values: float) -> torch.Tensor:
    return torch.tensor(values, dtype=F64)


# --- schedule (Eq. 10) ---------------------------------------------------------------------


@pytest.mark.parametrize("schedule", [VPSchedule(), VPSchedule.printed()])
def test_schedule_boundaries_and_identity(schedule: VPSchedule) -> None:
    assert schedule.alpha(_t(0.0)).item() == 1.0
    assert schedule.sigma(_t(0.0)).item() == 0.0
    t = torch.linspace(0, 1, 101, dtype=F64)
    a, s = schedule.alpha(t), schedule.sigma(t)
    assert torch.allclose(a**2 + s**2, torch.ones_like(t), atol=1e-12)
    assert torch.allclose(schedule.lambda_(t[1:]), torch.log(a[1:] / s[1:]), atol=1e-10)
    assert (schedule.lambda_(t).diff() < 0).all()
    assert schedule.lambda_(_t(0.0)).item() == math.inf


def test_alpha_at_T_default_and_printed() -> None:
    assert VPSchedule() == VPSchedule(0.1, 20.0)
    a1 = VPSchedule().alpha(_t(1.0)).item()
    assert a1 == pytest.approx(math.exp(-19.9 / 4 - 0.05), rel=1e-12)
    assert a1 == pytest.approx(0.0066, abs=1e-4)
    printed = VPSchedule.printed()
    assert (printed.beta_min, printed.beta_max) == (0.002, 1.0)
    a1p = printed.alpha(_t(1.0)).item()
    assert a1p == pytest.approx(math.exp(-0.998 / 4 - 0.001), rel=1e-12)
    assert a1p == pytest.approx(0.78, abs=0.005)


def test_schedule_is_frozen() -> None:
    with pytest.raises(Exception):
        VPSchedule().beta_min = 1.0  # type: ignore[misc]


# --- time grid (Appendix B) and sampling times (Algorithm 2) ---------------------------------


def test_karras_grid() -> None:
    grid = karras_time_grid(dtype=F64)
    assert grid.shape == (50,)
    assert grid[0].item() == 0.002 and grid[-1].item() == 1.0
    assert (grid.diff() > 0).all()
    i = 10  # 1-based index 11
    expected = (0.002**0.5 + i / 49 * (1 - 0.002**0.5)) ** 2
    assert grid[i].item() == pytest.approx(expected, rel=1e-12)
    linear = karras_time_grid(n=7, eps=0.1, t_max=0.7, rho=1.0, dtype=F64)
    assert torch.allclose(linear, torch.linspace(0.1, 0.7, 7, dtype=F64))
    assert karras_time_grid().dtype == torch.float32
    with pytest.raises(ValueError):
        karras_time_grid(n=1)


@pytest.mark.parametrize("k", [1, 2, 3, 5, 10, 49, 50])
def test_sampling_times(k: int) -> None:
    grid = karras_time_grid(dtype=F64)
    times = sampling_times(grid, k)
    assert times.shape == (k,)
    assert times[0].item() == 1.0
    assert (times.diff() < 0).all()
    assert torch.isin(times, grid).all()
    if k == 50:
        assert torch.equal(times, grid.flip(0))


@pytest.mark.parametrize("k", [0, 51, -1])
def test_sampling_times_rejects_bad_k(k: int) -> None:
    with pytest.raises(ValueError):
        sampling_times(karras_time_grid(), k)


# --- consistency parameterization (Eq. 11), target (Eq. 14), distance (Eq. 15) ---------------


def test_c_skip_c_out_values() -> None:
    t = _t(0.002)
    # (10 t)^2 = 4e-4, eta^2 = 0.25
    assert c_skip(t).item() == pytest.approx(0.25 / 0.2504, rel=1e-12)
    assert c_out(t).item() == pytest.approx(0.02 / math.sqrt(0.2504), rel=1e-12)
    assert c_skip(t).item() == pytest.approx(0.998, abs=5e-4)
    assert c_out(t).item() == pytest.approx(0.04, abs=5e-4)
    assert c_skip(_t(0.0)).item() == 1.0 and c_out(_t(0.0)).item() == 0.0


def test_c_skip_plus_c_out_squared_is_one() -> None:
    # eta^2 / (s^2 + eta^2) + s^2 / (s^2 + eta^2) = 1, s = scale t
    t = torch.linspace(0, 1, 33, dtype=F64)
    for eta, scale in [(0.5, 10.0), (0.3, 1.0)]:
        total = c_skip(t, eta, scale) + c_out(t, eta, scale) ** 2
        assert torch.allclose(total, torch.ones_like(t), atol=1e-12)


def test_consistency_output() -> None:
    g = torch.Generator().manual_seed(0)
    x = torch.randn(3, 4, 5, generator=g)
    f = torch.randn(3, 4, 5, generator=g)
    assert torch.equal(consistency_output(x, f, torch.zeros(3)), x)
    t = torch.tensor([0.0, 0.1, 1.0])
    out = consistency_output(x, f, t)
    for b in range(3):
        expected = c_skip(t[b]) * x[b] + c_out(t[b]) * f[b]
        assert torch.allclose(out[b], expected)


def test_pseudo_huber() -> None:
    a = torch.randn(4, 3, 8, generator=torch.Generator().manual_seed(1))
    assert pseudo_huber(a, a.clone()).item() == 0.0
    d = 0.7
    assert pseudo_huber(a + d, a, c=0.001).item() == pytest.approx(d - 0.001, abs=1e-6)
    x = (torch.randn(1000, generator=torch.Generator().manual_seed(2)) * 5).requires_grad_()
    (pseudo_huber(x, torch.zeros(1000)) * x.numel()).backward()  # undo the mean
    assert x.grad is not None and x.grad.abs().max().item() <= 1.0


def test_guided_target() -> None:
    g = torch.Generator().manual_seed(3)
    x0 = torch.randn(2, 3, 4, generator=g)
    u = torch.randn(2, 3, 4, generator=g)
    assert torch.equal(guided_target(x0, u, 0.0), x0.clamp(-1, 1))
    assert torch.allclose(guided_target(x0, u, 1.0), (2 * x0 - u).clamp(-1, 1))
    small_x0, small_u = x0.clamp(-0.3, 0.3), u.clamp(-0.3, 0.3)  # |2 x0 - u| <= 0.9: no clamp
    assert torch.allclose(guided_target(small_x0, small_u, 1.0), 2 * small_x0 - small_u)
    assert guided_target(x0 * 10, u, 2.0).abs().max().item() <= 1.0


# --- solver step (Eq. 12) -------------------------------------------------------------------


@pytest.mark.parametrize("schedule", [VPSchedule(), VPSchedule.printed()])
def test_dpm_solver_equals_ddim_and_is_exact(schedule: VPSchedule) -> None:
    g = torch.Generator().manual_seed(4)
    x0 = torch.rand(4, 3, 6, generator=g, dtype=F64) * 2 - 1
    noise = torch.randn(4, 3, 6, generator=g, dtype=F64)
    t = _t(1.0, 0.5, 0.2, 0.01)
    s = _t(0.8, 0.1, 0.0, 0.002)
    a_t, s_t = schedule.alpha(t)[:, None, None], schedule.sigma(t)[:, None, None]
    a_s, s_s = schedule.alpha(s)[:, None, None], schedule.sigma(s)[:, None, None]
    x_t = a_t * x0 + s_t * noise
    other = torch.randn(4, 3, 6, generator=g, dtype=F64)  # an arbitrary x0 estimate
    assert torch.allclose(
        dpm_solver_1_step(x_t, other, t, s, schedule), ddim_step(x_t, other, t, s, schedule)
    )
    closed = a_s * other + s_s * (x_t - a_t * other) / s_t
    assert torch.allclose(ddim_step(x_t, other, t, s, schedule), closed)
    # with the true clean sample the step lands exactly on the same trajectory at s
    target = a_s * x0 + s_s * noise
    assert torch.allclose(dpm_solver_1_step(x_t, x0, t, s, schedule), target, atol=1e-10)
    assert torch.allclose(ddim_step(x_t, x0, t, s, schedule), target, atol=1e-10)


# --- quantization (Eq. 8) -------------------------------------------------------------------


def test_quantize_grid_bounds_and_straight_through() -> None:
    z = (torch.randn(2, 3, 64, generator=torch.Generator().manual_seed(5)) * 3).requires_grad_()
    for levels in (1000, 7):
        q = quantize(z, levels)
        k = q.detach().double() * levels
        assert torch.allclose(k, k.round(), atol=1e-3)
        assert q.abs().max().item() <= 1.0
        assert torch.equal(q, torch.round(levels * torch.tanh(z.detach())) / levels)
    q = quantize(z)
    grad = torch.randn_like(q)
    q.backward(grad)
    assert torch.allclose(z.grad, grad * (1 - torch.tanh(z.detach()) ** 2))


def test_quantize_bf16_and_autocast() -> None:
    z = torch.randn(4, 16, generator=torch.Generator().manual_seed(6)).to(torch.bfloat16)
    z.requires_grad_()
    q = quantize(z)
    assert q.dtype == torch.bfloat16
    expected = (torch.round(1000 * torch.tanh(z.detach().float())) / 1000).to(torch.bfloat16)
    assert torch.equal(q, expected)
    q.sum().backward()
    assert z.grad is not None and z.grad.dtype == torch.bfloat16
    expected_grad = (1 - torch.tanh(z.detach().float()) ** 2).to(torch.bfloat16)
    assert torch.equal(z.grad, expected_grad)
    x = torch.randn(4, 16)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        assert quantize(x).dtype == torch.float32
        assert torch.equal(quantize(x), torch.round(1000 * torch.tanh(x)) / 1000)


def test_quantize_rejects_bad_levels() -> None:
    with pytest.raises(ValueError):
        quantize(torch.zeros(3), levels=0)
