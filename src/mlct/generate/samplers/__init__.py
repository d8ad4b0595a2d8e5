"""Samplers as objects, one file each, and their registry.

A sampler owns its time schedule and `sample(model, x, cond, steps)` (base.py); the equations
are mlct.diffusion.samplers' pure functions. A bundle names its sampler in config.json
("sampler": "consistency" | "ddim") and `sampler_class` turns that name into the class; no
caller compares sampler names. A new sampler is a file here and a line in SAMPLERS.
"""

from __future__ import annotations

from mlct.errors import MlctError
from mlct.generate.samplers.base import Sampler
from mlct.generate.samplers.consistency import ConsistencySampler
from mlct.generate.samplers.ddim import DDIMSampler

# by the name bundles record; for a stage, the first listed is the one `mlct export` records
SAMPLERS: dict[str, type[Sampler]] = {cls.name: cls for cls in (
    ConsistencySampler,  # Algorithm 2: MLCT models (mlct train cm)
    DDIMSampler,  # DDIM + classifier-free guidance: the diffusion baseline (mlct train diffusion)
)}


def sampler_class(name: object) -> type[Sampler]:
    """The sampler a bundle names; MlctError naming the known ones otherwise."""
    if not isinstance(name, str) or name not in SAMPLERS:
        raise MlctError(f"unknown sampler {name!r} ({', '.join(SAMPLERS)})")
    return SAMPLERS[name]


def sampler_for_stage(stage: str) -> type[Sampler] | None:
    """The sampler of the models a training stage makes (None: the stage makes none)."""
    return next((cls for cls in SAMPLERS.values() if cls.stage == stage), None)


__all__ = ["SAMPLERS", "ConsistencySampler", "DDIMSampler", "Sampler", "sampler_class",
           "sampler_for_stage"]
