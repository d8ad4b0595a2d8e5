"""Dropout whose mask is drawn by NumPy's PCG64 rather than PyTorch's CPU Bernoulli sampler.

Why: on the CPU, PyTorch draws a dropout mask one Mersenne-Twister number per element. In a
stage-2 training step of the `small` preset (batch 64, bf16 autocast, this repository's 2-core
Intel host) the denoiser's dropouts took 26% of the step, more than all its matrix products
(docs/training.md, "Dropout's random numbers on the CPU"). PCG64 hands out 64 random bits per
call of its raw generator, four 16-bit draws: the mask of a 64 x 8 x 1024 activation costs
0.25 ms instead of ~2.7.

The mask keeps an element when its 16-bit draw is at least round(p * 65536): the dropout rate
is p to within 1/65536 (0.1 -> 0.100006). The generator is seeded per call from PyTorch's own
(one draw), so `torch.manual_seed` and the checkpoints' saved RNG state still make a run
repeatable. Off the CPU, and in eval mode, it is F.dropout itself.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

_LEVELS = 1 << 16


def keep_mask(shape: torch.Size, p: float) -> Tensor:
    """(shape) bool: True where kept; each element dropped with probability
    round(p * 65536) / 65536."""
    n = int(np.prod(shape)) if len(shape) else 1
    seed = int(torch.randint(0, 2**62, (1,)))  # from PyTorch's generator: runs repeat
    words = np.random.Generator(np.random.PCG64(seed)).bit_generator.random_raw(-(-n // 4))
    draws = torch.from_numpy(words.view(np.int16)[:n]).view(shape)  # uniform over int16
    threshold = round(p * _LEVELS) - _LEVELS // 2  # int16 draws below it are dropped
    return draws >= threshold


class CheapDropout(nn.Module):
    """nn.Dropout's function with keep_mask's random numbers on the CPU."""

    def __init__(self, p: float) -> None:
        super().__init__()
        if not 0.0 <= p < 1.0:
            raise ValueError(f"dropout probability must be in [0, 1), got {p}")
        self.p = p

    def forward(self, x: Tensor) -> Tensor:
        if not self.training or self.p == 0.0:
            return x
        if x.device.type != "cpu":
            return F.dropout(x, self.p, True)
        # the scale applied in x's own arithmetic, as F.dropout does (a bfloat16 copy of
        # 1 / (1 - p) would bias every kept element by the scale's rounding, -0.16 % at p = 0.1)
        return torch.where(keep_mask(x.shape, self.p), x * (1.0 / (1.0 - self.p)), 0.0)

    def extra_repr(self) -> str:
        return f"p={self.p}"


def use_cheap_dropout(module: nn.Module) -> int:
    """Swap every nn.Dropout under `module` for a CheapDropout of the same p, in place (no
    weights change: a checkpoint reads the same); returns how many were swapped."""
    swapped = 0
    for name, child in module.named_children():
        if type(child) is nn.Dropout:
            setattr(module, name, CheapDropout(child.p))
            swapped += 1
        else:
            swapped += use_cheap_dropout(child)
    return swapped
