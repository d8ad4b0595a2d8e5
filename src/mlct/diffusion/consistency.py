"""Consistency parameterization (Eq. 11), guided target (Eq. 14) and distance (Eq. 15).

Pure functions: the network F is called elsewhere; these only combine its output with x_t.
"""

from __future__ import annotations

from torch import Tensor

from mlct.diffusion.schedule import append_dims


def c_skip(t: Tensor, eta: float = 0.5, scale: float = 10.0) -> Tensor:
    """Skip weight c_skip(t) = eta^2 / ((scale t)^2 + eta^2) (Eq. 11, as in LCM)."""
    return eta**2 / ((scale * t) ** 2 + eta**2)


def c_out(t: Tensor, eta: float = 0.5, scale: float = 10.0) -> Tensor:
    """Output weight c_out(t) = scale t / sqrt((scale t)^2 + eta^2) (Eq. 11, as in LCM)."""
    return scale * t / ((scale * t) ** 2 + eta**2).sqrt()


def consistency_output(
    x_t: Tensor, model_out: Tensor, t: Tensor, eta: float = 0.5, scale: float = 10.0
) -> Tensor:
    """S(x_t, t) = c_skip(t) x_t + c_out(t) F(x_t, t) (Eq. 11); t is (B,) or a scalar."""
    skip = append_dims(c_skip(t, eta, scale), x_t.ndim)  # (B, 1, 1)
    out = append_dims(c_out(t, eta, scale), x_t.ndim)  # (B, 1, 1)
    return skip * x_t + out * model_out  # (B, n, d)


def pseudo_huber(a: Tensor, b: Tensor, c: float = 0.001, per_sample: bool = False) -> Tensor:
    """Pseudo-Huber distance sqrt((a - b)^2 + c^2) - c (Eq. 15), averaged elementwise.

    per_sample=True averages over all but the batch dim, giving (B,), for per-sample weights.
    """
    d = ((a - b) ** 2 + c**2).sqrt() - c
    return d.flatten(1).mean(1) if per_sample else d.mean()


def guided_target(x0: Tensor, u: Tensor, w: float | Tensor, clamp: float | None = 1.0) -> Tensor:
    """Guided clean estimate clamp((1 + w) x0 - w u, -1, 1) (Eq. 14); detach u beforehand.

    clamp=None leaves it unbounded, for the latent ablations (vae, plain) that have no bound.
    """
    guided = (1 + w) * x0 - w * u
    return guided if clamp is None else guided.clamp(-clamp, clamp)
