"""Scalar quantization of the latent with a straight-through gradient (Sec. 4.1, Eq. 8).

z = round(l tanh(z_e)) / l: 2l + 1 levels per dimension, bounded in [-1, 1]. The forward pass is
exact; the backward pass is that of tanh alone, computed in float32 whatever the input dtype.
Note: bfloat16 has 8 mantissa bits and cannot hold the l = 1000 grid; the result is cast back to
the input dtype as asked, so feed float32 where the exact grid matters.
"""

from __future__ import annotations

import torch
from torch import Tensor


class _Quantize(torch.autograd.Function):
    """round(l tanh(z)) / l forward, d tanh(z) / dz backward (straight-through, Eq. 8)."""

    @staticmethod
    def forward(ctx, z_e: Tensor, levels: int) -> Tensor:  # type: ignore[override]
        ctx.save_for_backward(z_e)
        y = torch.tanh(z_e.float())  # fp32 even under autocast
        return (torch.round(levels * y) / levels).to(z_e.dtype)

    @staticmethod
    def backward(ctx, grad: Tensor) -> tuple[Tensor, None]:  # type: ignore[override]
        (z_e,) = ctx.saved_tensors
        y = torch.tanh(z_e.float())
        return (grad.float() * (1 - y * y)).to(z_e.dtype), None


def quantize(z_e: Tensor, levels: int = 1000) -> Tensor:
    """Quantize z_e to the grid k / levels, |z| <= 1, straight-through (Eq. 8). Shape kept."""
    if isinstance(levels, bool) or not isinstance(levels, int) or levels < 1:
        raise ValueError(f"levels must be a positive int, got {levels!r}")
    with torch.autocast(device_type=z_e.device.type, enabled=False):
        return _Quantize.apply(z_e, levels)
