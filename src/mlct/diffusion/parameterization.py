"""Wrappers that turn the raw network F(x_t, t, c) into a clean-latent estimate.

The network is separate from the process (as k-diffusion): these own the preconditioning and
nothing else. `ConsistencyFunction` is Eq. 11; the diffusion baseline predicts the noise, as MLD.
"""

from __future__ import annotations

from torch import Tensor, nn

from mlct.diffusion.consistency import consistency_output
from mlct.diffusion.schedule import VPSchedule, append_dims


class ConsistencyFunction(nn.Module):
    """S(x_t, t, c) = c_skip(t) x_t + c_out(t) F(x_t, t, c) (Eq. 11)."""

    def __init__(self, net: nn.Module, eta: float = 0.5, time_scale: float = 10.0) -> None:
        super().__init__()
        self.net = net
        self.eta = eta
        self.time_scale = time_scale

    def forward(self, x_t: Tensor, t: Tensor, cond: Tensor) -> Tensor:
        """x_t (B, n, d), t (B,), cond (B, text_dim) -> (B, n, d)."""
        return consistency_output(x_t, self.net(x_t, t, cond), t, self.eta, self.time_scale)


def x0_from_eps(x_t: Tensor, eps: Tensor, t: Tensor, schedule: VPSchedule) -> Tensor:
    """Clean estimate from a noise prediction: (x_t - sigma_t eps) / alpha_t (Eq. 10)."""
    alpha = append_dims(schedule.alpha(t), x_t.ndim)
    sigma = append_dims(schedule.sigma(t), x_t.ndim)
    return (x_t - sigma * eps) / alpha
