"""One-step ODE solvers from time t down to s < t, given a clean estimate x0 (Eq. 12)."""

from __future__ import annotations

import torch
from torch import Tensor

from mlct.diffusion.schedule import VPSchedule, append_dims


def dpm_solver_1_step(
    x_t: Tensor, x0: Tensor, t: Tensor, s: Tensor, schedule: VPSchedule
) -> Tensor:
    """First-order DPM-Solver++ step from t to s < t (Eq. 12); t, s are (B,) or scalars."""
    nd = x_t.ndim
    alpha_s = append_dims(schedule.alpha(s), nd)  # (B, 1, 1)
    sigma_s = append_dims(schedule.sigma(s), nd)
    sigma_t = append_dims(schedule.sigma(t), nd)
    h = append_dims(schedule.lambda_(s) - schedule.lambda_(t), nd)  # > 0 for s < t
    return (sigma_s / sigma_t) * x_t - alpha_s * torch.expm1(-h) * x0  # Eq. 12, (B, n, d)


def ddim_step(x_t: Tensor, x0: Tensor, t: Tensor, s: Tensor, schedule: VPSchedule) -> Tensor:
    """Deterministic DDIM step from t to s < t: alpha_s x0 + sigma_s eps_hat (equals Eq. 12)."""
    nd = x_t.ndim
    alpha_t = append_dims(schedule.alpha(t), nd)  # (B, 1, 1)
    sigma_t = append_dims(schedule.sigma(t), nd)
    alpha_s = append_dims(schedule.alpha(s), nd)
    sigma_s = append_dims(schedule.sigma(s), nd)
    eps_hat = (x_t - alpha_t * x0) / sigma_t  # (B, n, d)
    return alpha_s * x0 + sigma_s * eps_hat
