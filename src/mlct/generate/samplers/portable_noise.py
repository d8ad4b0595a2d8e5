"""Noise that a web page can draw too: a counter-based generator and Box-Muller, in 32-bit
integer arithmetic that JavaScript has exactly (Math.imul, >>> 0).

torch.Generator's normal draws (Mersenne Twister, then vectorised Box-Muller whose layout
depends on the tensor's size) cannot be reproduced in a browser. The static site of
`mlct export-web` (serve/site/noise.js) and this module draw the same numbers instead, so a
motion made in the page can be checked against the Python ONNX path for the same seed
(tests/test_web_static_e2e.py). Nothing else uses it: `mlct generate` keeps torch's noise.

The stream: word i = mix(key ^ mix(i)), mix the 32-bit integer hash "lowbias32" (Chris
Wellons' hash-prospector constants); a uniform in (0, 1) from two words (53 bits); a pair of
normals from two uniforms (Box-Muller, float64, then float32). The key folds the seed's low
and high 32 bits. Draws continue along the stream: x_T first, then each re-noising.

    noise = PortableNoise(seed)
    x = noise.randn((1, 3, 64))  # a torch.Tensor, float32
"""

from __future__ import annotations

import numpy as np
import torch

MASK = 0xFFFFFFFF
KEY_SALT = 0x9E3779B9  # the golden ratio's 32 bits: seed 0 does not give key 0


def mix(x: np.ndarray) -> np.ndarray:
    """lowbias32 on uint64 arrays holding 32-bit values (products masked back to 32 bits)."""
    x = x & MASK
    x ^= x >> 16
    x = (x * 0x7FEB352D) & MASK
    x ^= x >> 15
    x = (x * 0x846CA68B) & MASK
    x ^= x >> 16
    return x


def seed_key(seed: int) -> int:
    """The stream's 32-bit key from a seed in 0..2**63 - 1."""
    if not 0 <= int(seed) < 2**63:
        raise ValueError(f"seed must lie in 0..2**63 - 1, got {seed}")
    lo, hi = int(seed) & MASK, (int(seed) >> 32) & MASK
    inner = mix(np.array([hi ^ KEY_SALT], dtype=np.uint64))
    return int(mix(inner ^ np.uint64(lo))[0])


class PortableNoise:
    """N(0, 1) float32 draws along the counter stream of `seed`; `randn` is what
    mlct.diffusion.samplers.draw_noise calls on a generator that has it."""

    def __init__(self, seed: int) -> None:
        self.key = np.uint64(seed_key(seed))
        self.counter = 0  # words used so far

    def _words(self, count: int) -> np.ndarray:
        index = np.arange(self.counter, self.counter + count, dtype=np.uint64)
        self.counter += count
        return mix(self.key ^ mix(index))

    def normals(self, count: int) -> np.ndarray:
        """count standard normals (float32); an odd count still uses a whole pair."""
        pairs = (count + 1) // 2
        words = self._words(4 * pairs).reshape(pairs, 4)
        # 53-bit uniforms strictly inside (0, 1): (27 bits * 2^26 + 26 bits + 0.5) / 2^53
        u = ((words[:, 0::2] >> 5).astype(np.float64) * 67108864.0
             + (words[:, 1::2] >> 6).astype(np.float64) + 0.5) / 9007199254740992.0
        radius = np.sqrt(-2.0 * np.log(u[:, 0]))
        angle = 2.0 * np.pi * u[:, 1]
        z = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1).reshape(-1)
        return z[:count].astype(np.float32)

    def randn(self, shape: tuple[int, ...]) -> torch.Tensor:
        """A float32 tensor of `shape`, filled in C order."""
        return torch.from_numpy(self.normals(int(np.prod(shape))).reshape(shape))
