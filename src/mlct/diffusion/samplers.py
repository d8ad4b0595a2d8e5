"""Samplers: pure functions of a denoising function, a schedule and a generator.

`model(x, t)` closes over the condition; t is (B,). The consistency sampler is Algorithm 2 (one
network pass per step); the DDIM sampler is the baseline's, with classifier-free guidance done
by the caller's `model` (two passes per step).
"""

from __future__ import annotations

from typing import Callable, Sequence, Union

import torch
from torch import Tensor

from mlct.diffusion.schedule import VPSchedule
from mlct.diffusion.solver import dpm_solver_1_step

DenoiseFn = Callable[[Tensor, Tensor], Tensor]  # (x (B, n, d), t (B,)) -> x0 estimate


# one generator for the batch, or one per batch item
Generators = Union[torch.Generator, Sequence[torch.Generator], None]


def _randn(shape: tuple[int, ...], generator: Generators, like: Tensor) -> Tensor:
    # Noise is drawn on the generator's device (CPU for a CPU generator) then moved, so the
    # same seed gives the same motion on every device. A sequence holds one generator per batch
    # item: item i then gets the same noise whatever else is in the batch (server batching).
    if isinstance(generator, Sequence):
        if len(generator) != shape[0]:
            raise ValueError(f"{len(generator)} generators for a batch of {shape[0]}")
        return torch.stack([_randn(shape[1:], g, like) for g in generator])
    device = generator.device if generator is not None else like.device
    return torch.randn(shape, generator=generator, device=device,
                       dtype=torch.float32).to(like.device, like.dtype)


def sample_consistency(model: DenoiseFn, shape: tuple[int, ...], times: Tensor,
                       schedule: VPSchedule, generator: Generators = None,
                       clamp: float | None = 1.0) -> Tensor:
    """Multistep consistency sampling from T down through `times` (Algorithm 2). NFE = len(times)."""
    x = _randn(shape, generator, times)  # N(0, I), as Algorithm 2 (whatever alpha_T is)
    x0 = x
    for k, t in enumerate(times):
        x0 = model(x, t.expand(shape[0]))
        if clamp is not None:
            x0 = x0.clamp(-clamp, clamp)
        if k + 1 < len(times):  # re-noise to the next, lower time with fresh noise
            s = times[k + 1]
            x = schedule.alpha(s) * x0 + schedule.sigma(s) * _randn(shape, generator, times)
    return x0


def ddim_times(steps: int, t_max: float = 1.0, t_min: float = 1e-3,
               device: torch.device | str | None = None) -> Tensor:
    """steps + 1 times evenly spaced from T down to t_min, then 0 (the last step lands on x0)."""
    times = torch.linspace(t_max, t_min, steps, dtype=torch.float32, device=device)
    return torch.cat([times, times.new_zeros(1)])


def sample_ddim(model: DenoiseFn, shape: tuple[int, ...], times: Tensor, schedule: VPSchedule,
                generator: Generators = None, clamp: float | None = 1.0) -> Tensor:
    """Deterministic DDIM (first-order, Eq. 12) from times[0] to times[-1] = 0."""
    x = _randn(shape, generator, times)
    x0 = x
    for t, s in zip(times[:-1], times[1:]):
        x0 = model(x, t.expand(shape[0]))
        if clamp is not None:
            x0 = x0.clamp(-clamp, clamp)
        x = x0 if s == 0 else dpm_solver_1_step(x, x0, t, s, schedule)
    return x0
