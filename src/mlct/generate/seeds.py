"""Seeds: how a call's seed becomes each item's, and each item's its noise generator; and
`Sampling`, the rest of what a call's samples depend on.

An item's motion depends only on its own seed (not on the rest of its batch), so a motion is
replayed from (text, length, nfe, seed, candidates) whatever batch it was made in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from mlct.diffusion.torch_randn import TorchRandn
from mlct.errors import MlctError

if TYPE_CHECKING:
    import torch

SEED_STRIDE = 0x9E3779B97F4A7C15  # candidate k of seed s samples with s + k * this (mod 2^63)
MAX_SEED = 2**63 - 1  # torch.Generator.manual_seed takes 64 bits; kept signed for portability


@dataclass(frozen=True)
class Sampling:
    """How each batch of a generate() call is sampled: the step count (checked), the guidance
    scale (None: the sampler's) and the candidates per prompt. Made once from the call's nfe,
    guidance and candidates, and handed down whole to every path that samples."""

    steps: int
    guidance: float | None = None
    candidates: int = 1


def is_int(value: object) -> bool:
    """A whole number given as an int (not a bool, a float or a string)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def item_seeds(count: int, seed: int | Sequence[int] | None) -> list[int]:
    """One seed per item: an int s gives item i the seed s + i, a sequence one each; None is
    random, drawn here so that it is recorded on each motion and can be replayed."""
    if seed is None:
        return [int(s) for s in np.random.default_rng().integers(0, 2**31 - 1, count)]
    if is_int(seed):
        seeds = [int(seed) + i for i in range(count)]  # type: ignore[arg-type]
    elif isinstance(seed, (list, tuple, np.ndarray)) and all(is_int(s) for s in seed):
        seeds = [int(s) for s in seed]
    else:
        raise MlctError(f"seed must be a whole number or a list of them, got {seed!r}")
    if len(seeds) != count:
        raise MlctError(f"{len(seeds)} seeds for {count} texts")
    if any(not 0 <= s <= MAX_SEED for s in seeds):
        raise MlctError(f"seeds must lie in 0..{MAX_SEED} (item i uses seed + i), got {seed}")
    return seeds


def candidate_seeds(seeds: Sequence[int], candidates: int) -> list[int]:
    """The seeds of best-of-`candidates` sampling, item by item: a seed's first candidate is
    the plain sample of that seed, the others have seeds derived from it."""
    return [(s + k * SEED_STRIDE) % (MAX_SEED + 1) for s in seeds for k in range(candidates)]


def generators_for(seed: int | Sequence[int] | None) -> torch.Generator | list[torch.Generator]:
    """The noise generators of a batch: an int seeds one for the batch, a sequence one per
    item, None a random one."""
    import torch

    if seed is None:
        generator = torch.Generator()
        generator.seed()
        return generator
    if isinstance(seed, (int, np.integer)):
        return torch.Generator().manual_seed(int(seed))
    return [torch.Generator().manual_seed(int(s)) for s in seed]


def numpy_generators(seed: int | Sequence[int] | None) -> TorchRandn | list[TorchRandn]:
    """generators_for's generators drawn in numpy (diffusion/torch_randn.py): the same noise
    without torch, for the onnx backend. None: a random seed."""
    if seed is None:
        return TorchRandn(int(np.random.default_rng().integers(0, 2**63 - 1)))
    if isinstance(seed, (int, np.integer)):
        return TorchRandn(int(seed))
    return [TorchRandn(int(s)) for s in seed]

