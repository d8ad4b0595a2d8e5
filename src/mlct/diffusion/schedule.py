"""Variance-preserving schedule (Eq. 10) and the Karras-style time grid (Appendix B).

Times are continuous, t in [0, 1]. Every method takes a tensor of times of any shape and returns
a tensor of the same shape, dtype and device, so callers choose the precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor


def append_dims(t: Tensor, ndim: int) -> Tensor:
    """Reshape a (B,) or scalar tensor so it broadcasts over a tensor with `ndim` dims."""
    if t.ndim > ndim:
        raise ValueError(f"cannot broadcast a {t.ndim}-d tensor over {ndim} dims")
    return t.reshape(t.shape + (1,) * (ndim - t.ndim))


@dataclass(frozen=True)
class VPSchedule:
    """VP schedule with a linear beta(t) from beta_min to beta_max (Eq. 10)."""

    beta_min: float = 0.1  # b0; the authors' code. The paper prints 0.002 (see `printed`).
    beta_max: float = 20.0  # b1; the authors' code. The paper prints 1.

    @classmethod
    def printed(cls) -> VPSchedule:
        """The values the paper prints (b0 = 0.002, b1 = 1): alpha_1 = 0.78, barely noised."""
        return cls(beta_min=0.002, beta_max=1.0)

    def log_alpha(self, t: Tensor) -> Tensor:
        """log alpha_t = -t^2 (b1 - b0) / 4 - t b0 / 2 (Eq. 10)."""
        return -(t**2) * (self.beta_max - self.beta_min) / 4 - t * self.beta_min / 2

    def alpha(self, t: Tensor) -> Tensor:
        """Signal scale alpha_t (Eq. 10)."""
        return self.log_alpha(t).exp()

    def sigma(self, t: Tensor) -> Tensor:
        """Noise scale sigma_t = sqrt(1 - alpha_t^2) (Eq. 10)."""
        # The paper prints sigma_t = sqrt(1 - e^{2 alpha(t)}): a typo for 1 - e^{2 log alpha_t}
        # = 1 - alpha_t^2, the variance-preserving choice. -expm1 keeps precision near t = 0.
        return (-torch.expm1(2 * self.log_alpha(t))).sqrt()

    def lambda_(self, t: Tensor) -> Tensor:
        """Half log-SNR lambda_t = log(alpha_t / sigma_t) (Eq. 10); +inf at t = 0."""
        log_alpha = self.log_alpha(t)
        return log_alpha - 0.5 * torch.log(-torch.expm1(2 * log_alpha))


def karras_time_grid(
    n: int = 50,
    eps: float = 0.002,
    t_max: float = 1.0,
    rho: float = 2.0,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str | None = None,
) -> Tensor:
    """Increasing grid t_1 = eps < ... < t_n = T (Appendix B). Returns (n,)."""
    if n < 2:
        raise ValueError(f"the time grid needs n >= 2 points, got {n}")
    if not 0 < eps < t_max:
        raise ValueError(f"need 0 < eps < t_max, got eps={eps}, t_max={t_max}")
    frac = torch.linspace(0, 1, n, dtype=torch.float64)  # (i - 1) / (n - 1)
    lo, hi = eps ** (1 / rho), t_max ** (1 / rho)
    grid = (lo + frac * (hi - lo)) ** rho  # (n,)  Appendix B
    grid[0], grid[-1] = eps, t_max  # exact endpoints despite the power round trip
    return grid.to(dtype=dtype, device=device)


def sampling_times(grid: Tensor, k: int) -> Tensor:
    """K grid times from T down, evenly strided in index, T first (Algorithm 2). Returns (k,)."""
    n = grid.shape[0]
    if not 1 <= k <= n:
        raise ValueError(f"need 1 <= k <= {n} sampling steps, got {k}")
    # As LCM / MotionLCM: stride n // k from the top; k = n gives the whole grid, reversed.
    stride = n // k
    index = (n - 1) - stride * torch.arange(k, device=grid.device)  # (k,) decreasing
    return grid[index]
