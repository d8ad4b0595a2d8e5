"""Samplers: pure functions of a denoising function, a starting latent, a schedule, a generator.

`model(x, t)` closes over the condition; t is (B,). The consistency sampler is Algorithm 2 (one
network pass per step); the DDIM sampler is the baseline's, with classifier-free guidance done
by the caller's `model` (two passes per step). Both start from the given x (k-diffusion's
signature): pure noise from `draw_noise`, or a latent that the caller partly knows.
The objects that pick the times and wrap the network are mlct.generate.samplers.
"""

from __future__ import annotations

from typing import Callable, Sequence, Union

import torch
from torch import Tensor

from mlct.diffusion.schedule import VPSchedule
from mlct.diffusion.solver import dpm_solver_1_step

DenoiseFn = Callable[[Tensor, Tensor], Tensor]  # (x (B, n, d), t (B,)) -> x0 estimate
GuideFn = Callable[[Tensor], Tensor]  # x0 (B, n, d) -> x0 moved towards a control


# one generator for the batch, or one per batch item; or any object with randn(shape) -> Tensor
# (the web page's portable noise, mlct.generate.samplers.portable_noise)
Generators = Union[torch.Generator, Sequence[torch.Generator], object, None]


def draw_noise(shape: tuple[int, ...], generator: Generators, like: Tensor) -> Tensor:
    """N(0, I) of `shape` with like's device and dtype, drawn from `generator` (see below)."""
    # Noise is drawn on the generator's device (CPU for a CPU generator) then moved, so the
    # same seed gives the same motion on every device. A sequence holds one generator per batch
    # item: item i then gets the same noise whatever else is in the batch (server batching).
    if isinstance(generator, Sequence):
        if len(generator) != shape[0]:
            raise ValueError(f"{len(generator)} generators for a batch of {shape[0]}")
        return torch.stack([draw_noise(shape[1:], g, like) for g in generator])
    if hasattr(generator, "randn"):  # a portable stream (generate/samplers/portable_noise.py)
        return generator.randn(shape).to(like.device, like.dtype)
    device = generator.device if generator is not None else like.device
    return torch.randn(shape, generator=generator, device=device,
                       dtype=torch.float32).to(like.device, like.dtype)


def sample_consistency(model: DenoiseFn, x: Tensor, times: Tensor, schedule: VPSchedule,
                       generator: Generators = None, clamp: float | None = 1.0,
                       guide: GuideFn | None = None) -> Tensor:
    """Multistep consistency sampling from x at T down through `times` (Algorithm 2); NFE = K.
    guide: a correction of each step's clean estimate x0 (sampling-time control)."""
    # x: (B, n, d), N(0, I) as Algorithm 2 (whatever alpha_T is) unless the caller knows more
    shape = tuple(x.shape)
    x0 = x
    for k, t in enumerate(times):
        x0 = model(x, t.expand(shape[0]))
        if clamp is not None:
            x0 = x0.clamp(-clamp, clamp)
        if guide is not None:
            x0 = guide(x0) if clamp is None else guide(x0).clamp(-clamp, clamp)
        if k + 1 < len(times):  # re-noise to the next, lower time with fresh noise
            s = times[k + 1]
            x = schedule.alpha(s) * x0 + schedule.sigma(s) * draw_noise(shape, generator, times)
    return x0


def ddim_times(steps: int, t_max: float = 1.0, t_min: float = 1e-3,
               device: torch.device | str | None = None) -> Tensor:
    """steps + 1 times evenly spaced from T down to t_min, then 0 (the last step lands on x0)."""
    times = torch.linspace(t_max, t_min, steps, dtype=torch.float32, device=device)
    return torch.cat([times, times.new_zeros(1)])


def sample_ddim(model: DenoiseFn, x: Tensor, times: Tensor, schedule: VPSchedule,
                clamp: float | None = 1.0, guide: GuideFn | None = None) -> Tensor:
    """Deterministic DDIM (first-order, Eq. 12) from x at times[0] to times[-1] = 0.
    guide: a correction of each step's clean estimate x0 (sampling-time control)."""
    x0 = x
    last = len(times) - 2  # the step to times[-1] = 0 lands on x0: no solver step after it
    for k, (t, s) in enumerate(zip(times[:-1], times[1:])):
        x0 = model(x, t.expand(x.shape[0]))
        if clamp is not None:
            x0 = x0.clamp(-clamp, clamp)
        if guide is not None:
            x0 = guide(x0) if clamp is None else guide(x0).clamp(-clamp, clamp)
        if k < last:  # by index, not by reading s: a CUDA graph cannot read the device
            x = dpm_solver_1_step(x, x0, t, s, schedule)
    return x0
