"""The consistency sampler: multistep sampling of an MLCT model (Algorithm 2).

The guidance w was trained into the model (Eq. 14), so one network pass per step and no scale
to choose; the steps are K of the N grid times (Appendix B), T first.
"""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

from mlct.generate.samplers.base import Sampler, with_condition_terms

if TYPE_CHECKING:
    import torch
    from torch import Tensor, nn

    from mlct.config import Config
    from mlct.diffusion.samplers import Generators, GuideFn


class ConsistencySampler(Sampler):
    """Algorithm 2 on the consistency function S = c_skip x_t + c_out F (Eq. 11)."""

    name = "consistency"
    stage = "cm"
    method = "MLCT"
    steps_unit = "NFE"
    steps_option = "nfe"

    def __init__(self, config: Config, device: torch.device | str | None = None) -> None:
        super().__init__(config, device)
        s = config.schedule
        self.eta, self.time_scale = s.eta, s.time_scale
        self._grid_size = s.num_steps  # karras_time_grid's N points
        self._default_steps = config.consistency.nfe
        self._trained_guidance = config.consistency.guidance

    @cached_property
    def grid(self) -> Tensor:
        """(N,) increasing: the grid of training (Algorithm 1) and of sampling (Algorithm 2)."""
        from mlct.diffusion.schedule import karras_time_grid

        s = self.config.schedule
        return karras_time_grid(s.num_steps, s.eps, s.t_max, s.rho, device=self.device)

    @property
    def default_steps(self) -> int:
        return self._default_steps

    @property
    def max_steps(self) -> int:
        return self._grid_size

    def guidance(self, scale: float | None = None) -> float:
        return self._trained_guidance  # w is trained in; a scale given here does not apply

    def noise_draws(self, steps: int) -> int:
        return steps - 1  # Algorithm 2 re-noises before every step but the first

    def times(self, steps: int) -> Tensor:
        from mlct.diffusion.schedule import sampling_times

        return sampling_times(self.grid, steps)  # (K,)

    def sample(self, model: nn.Module, x: Tensor, cond: Tensor, steps: int | None = None, *,
               generator: Generators = None, guidance: float | None = None,
               uncond: Tensor | None = None, guide: GuideFn | None = None) -> Tensor:
        from mlct.diffusion.consistency import consistency_output
        from mlct.diffusion.samplers import sample_consistency

        times = self.times(self.check_steps(steps))

        network = with_condition_terms(model, cond, times)  # the text and time terms, once

        def consistency(x_t: Tensor, t: Tensor) -> Tensor:  # S(x_t, t, c), Eq. 11
            return consistency_output(x_t, network(x_t, t, cond), t, self.eta, self.time_scale)

        return sample_consistency(consistency, x, times, self.schedule, generator, self.clamp,
                                  guide)
