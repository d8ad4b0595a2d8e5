"""torch.randn's CPU draws in numpy: the onnx backend samples without torch and still gives a
seed the torch backend's motion.

A seeded `torch.Generator()` (CPU) is a 32-bit Mersenne Twister seeded with the seed's low 32
bits (init_genrand), numpy's MT19937 under its legacy seeding exactly. `torch.randn` of a
float32 tensor of 16 values or more (ATen's normal_fill) takes one 32-bit word per value as a
uniform (its low 24 bits / 2**24), then Box-Muller on each block of 16: values j and j + 8 from
u1 = 1 - u[j], u2 = u[j + 8]; a size that is not a multiple of 16 draws 16 more words and
recomputes the last 16 values from them. The generator then stands where torch's would, so
successive draws (x_T, each re-noising) follow torch's too.

The uniforms and the stream are torch's bit for bit; the log, cos and sin are numpy's float32
ones, torch's AVX2 kernel its own approximations: the normals agree to 1-2 units in the last
place (tests/test_torch_randn.py), far below what moves a motion.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

BLOCK = 16  # normal_fill's Box-Muller block: 8 pairs (j, j + 8)
_U24 = np.float32(2.0**-24)


class TorchRandn:
    """The draws of `torch.Generator().manual_seed(seed)` for float32 randn of 16+ values."""

    def __init__(self, seed: int) -> None:
        self.seed = int(seed)
        self._bits = np.random.MT19937(0)
        self._bits._legacy_seeding(self.seed & 0xFFFFFFFF)  # torch keeps the low 32 bits

    def _uniform(self, count: int) -> np.ndarray:
        words = self._bits.random_raw(count).astype(np.uint32)  # mt19937's 32-bit outputs
        return (words & 0xFFFFFF).astype(np.float32) * _U24  # [0, 1), 24 bits

    def randn(self, shape: Sequence[int]) -> np.ndarray:
        """torch.randn(*shape, generator=g) as a float32 array, g advanced as torch does."""
        return self.randn_many(shape, 1)[0]

    def randn_many(self, shape: Sequence[int], count: int) -> np.ndarray:
        """`count` successive randn(shape) draws at once: (count, *shape), float32."""
        shape = tuple(int(s) for s in shape)
        size = int(np.prod(shape))
        if size < BLOCK:  # torch draws these one at a time, with another transform
            raise ValueError(f"TorchRandn draws 16 values or more, not {size}")
        tail = BLOCK if size % BLOCK else 0  # the words of the recomputed last block
        words = self._uniform(count * (size + tail)).reshape(count, size + tail)
        whole = size - size % BLOCK
        out = np.empty((count, size), np.float32)
        out[:, :whole] = _box_muller(words[:, :whole])
        if tail:
            out[:, size - BLOCK:] = _box_muller(words[:, size:])
        return out.reshape((count, *shape))


def _box_muller(uniform: np.ndarray) -> np.ndarray:
    """Rows of blocks of 16 uniforms (k, 16 m) -> 16 normals each (normal_fill_16), float32."""
    blocks = uniform.reshape(len(uniform), -1, BLOCK)
    half = BLOCK // 2
    radius = np.sqrt(np.float32(-2.0) * np.log(np.float32(1.0) - blocks[..., :half]))
    theta = np.float32(2.0 * np.pi) * blocks[..., half:]
    return np.concatenate([radius * np.cos(theta), radius * np.sin(theta)],
                          axis=-1).reshape(len(uniform), -1)
