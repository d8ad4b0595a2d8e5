"""diffusion/torch_randn.py against torch.randn: the same stream, the same normals to an ulp."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.diffusion.torch_randn import TorchRandn

torch = pytest.importorskip("torch")


@pytest.mark.parametrize("seed", [0, 7, 2**31 - 1, 2**40 + 3, 2**63 - 1])
def test_successive_draws_follow_torchs_generator(seed):
    generator = torch.Generator().manual_seed(seed)
    mine = TorchRandn(seed)
    for shape in [(1, 6, 192), (8, 6, 192), (3, 7, 5), (16,), (2, 9)]:  # whole blocks and not
        expected = torch.randn(*shape, generator=generator).numpy()
        got = mine.randn(shape)
        assert got.dtype == np.float32 and got.shape == expected.shape
        assert np.abs(got - expected).max() < 1e-5 * max(1.0, np.abs(expected).max())


def test_many_draws_at_once_are_the_draws_one_by_one():
    for shape in [(6, 192), (3, 7, 5)]:
        one, many = TorchRandn(11), TorchRandn(11)
        expected = np.stack([one.randn(shape) for _ in range(4)])
        assert np.array_equal(many.randn_many(shape, 4), expected)
        assert np.array_equal(many.randn(shape), one.randn(shape))  # both streams stand alike


def test_fewer_than_a_block_is_refused():
    with pytest.raises(ValueError, match="16 values or more"):
        TorchRandn(0).randn((3, 5))
