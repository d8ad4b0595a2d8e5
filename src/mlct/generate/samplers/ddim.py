"""The DDIM sampler with classifier-free guidance: the latent diffusion baseline's (as MLD).

The network predicts the noise; each step runs it on the condition and on the null condition
(one batch of 2B) and mixes the two with the guidance scale; deterministic DDIM (Eq. 12).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mlct.generate.samplers.base import Sampler, with_condition_terms

if TYPE_CHECKING:
    import torch
    from torch import Tensor, nn

    from mlct.config import Config
    from mlct.diffusion.samplers import Generators, GuideFn

# The smallest time the baseline is trained and sampled at (t ~ U(t_min, 1),
# diffusion_training_loss); a step shorter than it is finer than anything the model has seen,
# so at most 1 / T_MIN steps (1000, DDPM's horizon).
T_MIN = 1e-3


class DDIMSampler(Sampler):
    """DDIM from T to 0 in evenly spaced steps, with classifier-free guidance."""

    name = "ddim"
    stage = "diffusion"
    method = "DDIM"
    steps_unit = "steps"
    steps_option = "ddim_steps"
    cfg = True

    def __init__(self, config: Config, device: torch.device | str | None = None) -> None:
        super().__init__(config, device)
        self._default_steps = config.diffusion.sample_steps
        self._default_guidance = config.diffusion.guidance

    @property
    def default_steps(self) -> int:
        return self._default_steps

    @property
    def max_steps(self) -> int:
        return round(1 / T_MIN)

    def guidance(self, scale: float | None = None) -> float:
        return self._default_guidance if scale is None else float(scale)

    def describe(self, scale: float | None = None) -> str:
        return f"{self.method}, CFG {self.guidance(scale):g}"

    def times(self, steps: int) -> Tensor:
        from mlct.diffusion.samplers import ddim_times

        return ddim_times(steps, t_min=T_MIN, device=self.device)  # (steps + 1,), last 0

    def sample(self, model: nn.Module, x: Tensor, cond: Tensor, steps: int | None = None, *,
               generator: Generators = None, guidance: float | None = None,
               uncond: Tensor | None = None, guide: GuideFn | None = None) -> Tensor:
        if uncond is None:
            raise ValueError("classifier-free guidance needs the null condition (uncond)")
        times = self.times(self.check_steps(steps))
        scale = self.guidance(guidance)
        import torch

        from mlct.diffusion.parameterization import x0_from_eps
        from mlct.diffusion.samplers import sample_ddim

        both = torch.cat([cond, uncond.expand_as(cond)])  # (2B, c): cond, null
        network = with_condition_terms(model, both, times)

        def guided(x_t: Tensor, t: Tensor) -> Tensor:
            # Classifier-free guidance: two passes (one batch of 2B) per step.
            eps_c, eps_u = network(torch.cat([x_t, x_t]), torch.cat([t, t]), both).chunk(2)
            return x0_from_eps(x_t, eps_u + scale * (eps_c - eps_u), t, self.schedule)

        return sample_ddim(guided, x, times, self.schedule, self.clamp, guide)
