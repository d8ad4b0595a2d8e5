"""The sampler interface: a time schedule and `sample(model, x, cond, steps)`.

A sampler object is built from a run's config (schedule, clamp, default steps) and wraps one of
mlct.diffusion.samplers' pure functions, which hold the equations. It takes the raw network
F(x_t, t, c) and applies its parameterization (Eq. 11 or the noise prediction) itself, and it
takes the starting latent x, so that a caller can hand in a partly known latent (control,
editing) as well as the noise of `noise()`. Samplers never load or save anything.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from functools import cached_property, partial
from typing import TYPE_CHECKING, Any, Callable, ClassVar

from mlct.config_view import latent_clamp
from mlct.errors import MlctError

if TYPE_CHECKING:  # torch is imported when a sampler samples, not when it is made: the onnx
    import torch  # backend reads its steps and clamp without torch (backends/onnx/sampler.py)
    from torch import Tensor, nn

    from mlct.config import Config

    from mlct.diffusion.samplers import Generators, GuideFn
    from mlct.diffusion.schedule import VPSchedule


class Sampler(ABC):
    """Sampling of one kind of stage-2 model; subclasses set the class attributes."""

    name: ClassVar[str]  # what a bundle's config.json records under "sampler"
    stage: ClassVar[str]  # the training stage (mlct train STAGE) whose networks it samples
    method: ClassVar[str]  # the method's short name in reports
    steps_unit: ClassVar[str]  # what its step count is called in reports: "NFE" or "steps"
    steps_option: ClassVar[str]  # the `mlct eval` option that sweeps its steps (nfe, ddim_steps)
    # True: classifier-free guidance at sampling time, so the scale is a sampling choice and
    # each step runs the network on the condition and on the null condition (2 passes).
    cfg: ClassVar[bool] = False

    def __init__(self, config: Config, device: torch.device | str | None = None) -> None:
        self.config = config
        self._device = device
        self.clamp = latent_clamp(config)  # None for the unbounded latents (vae, plain)

    @cached_property
    def device(self) -> torch.device:
        import torch

        return torch.device("cpu") if self._device is None else torch.device(self._device)

    @cached_property
    def schedule(self) -> VPSchedule:
        from mlct.diffusion.schedule import VPSchedule

        return VPSchedule(self.config.schedule.beta_min, self.config.schedule.beta_max)

    @property
    def passes_per_step(self) -> int:
        """Network passes (of the batch) per step: 2 with classifier-free guidance."""
        return 2 if self.cfg else 1

    @property
    @abstractmethod
    def default_steps(self) -> int:
        """The step count of a call that names none (the run's config)."""

    @property
    @abstractmethod
    def max_steps(self) -> int:
        """The most steps this model can be sampled with."""

    @abstractmethod
    def guidance(self, scale: float | None = None) -> float:
        """The guidance a call with `scale` samples under (the trained w, or the CFG scale)."""

    @abstractmethod
    def times(self, steps: int) -> Tensor:
        """The times a run of `steps` steps evaluates the network at, T first."""

    @abstractmethod
    def sample(self, model: nn.Module, x: Tensor, cond: Tensor, steps: int | None = None, *,
               generator: Generators = None, guidance: float | None = None,
               uncond: Tensor | None = None, guide: GuideFn | None = None) -> Tensor:
        """Clean latents (B, n, d) from x (B, n, d) at T, for conditions cond (B, c).

        model: the network F(x_t, t, c); uncond: the null condition (1, c), needed when `cfg`;
        generator: the noise that a stochastic sampler draws after x; guide: moves each step's
        clean estimate towards a control (generate/control/controlled.py)."""

    def describe(self, scale: float | None = None) -> str:
        """The sampler and its guidance, for a report's method name: 'MLCT, w=1'."""
        return f"{self.method}, w={self.guidance(scale):g}"

    def check_steps(self, steps: int | None) -> int:
        """The step count to sample with (the default for None); MlctError when out of range."""
        steps = self.default_steps if steps is None else int(steps)
        if not 1 <= steps <= self.max_steps:
            raise MlctError(f"nfe must be within 1..{self.max_steps}, got {steps}")
        return steps

    def noise_draws(self, steps: int) -> int:
        """How many draws of fresh noise, each of x_T's shape, a run of `steps` makes after
        x_T, in order (a CUDA graph takes them all as one input): none, for a deterministic
        sampler."""
        return 0

    def noise(self, shape: tuple[int, ...], generator: Generators = None) -> Tensor:
        """x_T ~ N(0, I) of `shape` (B, n, d) on the sampler's device, float32 (see draw_noise)."""
        import torch

        from mlct.diffusion.samplers import draw_noise

        return draw_noise(shape, generator, torch.empty(0, device=self.device))


def with_condition_terms(model: Any, cond: Tensor, times: Tensor) -> Callable[..., Tensor]:
    """The network F(x_t, t, c) of one sampling run under the condition `cond` at `times`: with
    the condition's terms computed once and passed to every step (the ConditionCache of
    mlct.nn.denoiser.Denoiser.condition_terms) where the network has them; as it is otherwise."""
    terms = getattr(model, "condition_terms", None)
    return model if terms is None else partial(model, cache=terms(cond, times))
