"""consistency.text_noise: Gaussian noise on stage 2's training text vectors."""

from __future__ import annotations

import torch

from mlct.config import config_from_dict
from mlct.train.stages import noisy_text


def test_zero_noise_leaves_the_vectors_alone():
    cond = torch.randn(4, 384)
    assert noisy_text(cond, 0.0) is cond


def test_the_noise_is_the_given_share_of_each_vector_norm():
    cond = torch.nn.functional.normalize(torch.randn(2000, 384), dim=-1)
    cond[:1000] *= 3.0  # a side-contrasted caption is longer; its noise grows with it
    noisy = noisy_text(cond, 0.5, torch.Generator().manual_seed(0))
    share = (noisy - cond).norm(dim=-1) / cond.norm(dim=-1)
    assert abs(float(share.mean()) - 0.5) < 0.01
    assert float(torch.cosine_similarity(noisy, cond).mean()) > 0.85
    # seeded: the same generator state gives the same noise
    again = noisy_text(cond, 0.5, torch.Generator().manual_seed(0))
    assert torch.equal(noisy, again)


def test_the_config_takes_it_and_refuses_a_negative_one():
    import pytest

    from mlct.errors import MlctError

    assert config_from_dict({"consistency": {"text_noise": 0.5}}).consistency.text_noise == 0.5
    assert config_from_dict({}).consistency.text_noise == 0.0
    with pytest.raises(MlctError, match="consistency.text_noise"):
        config_from_dict({"consistency": {"text_noise": -1.0}})


def test_caption_shaped_noise_moves_a_vector_only_as_the_captions_differ():
    """Residuals in a 2-d plane of 384: the noise stays in that plane, and its spread is the
    residuals' own (times the scale)."""
    generator = torch.Generator().manual_seed(1)
    plane = torch.zeros(2, 384)
    plane[0, 3] = plane[1, 7] = 1.0
    residuals = torch.randn(500, 2, generator=generator) @ plane * 0.3  # (500, 384)
    cond = torch.nn.functional.normalize(torch.randn(4000, 384, generator=generator), dim=-1)
    noise = noisy_text(cond, 2.0, generator, residuals) - cond
    off_plane = noise.clone()
    off_plane[:, [3, 7]] = 0
    assert float(off_plane.abs().max()) < 1e-6
    # a unit Gaussian mix of residuals of variance 0.09 per axis, times 2: std 0.6 per axis
    assert abs(float(noise[:, 3].std()) - 0.6) < 0.05 and abs(float(noise[:, 7].std()) - 0.6) < 0.05


def test_caption_residuals_are_each_group_about_its_mean():
    from mlct.errors import MlctError
    from mlct.train.stages import TextTable

    class Words:  # a stand-in encoder: one axis per word
        name, dim = "words", 3
        vocab = ["walks", "strolls", "jumps"]

        def encode(self, texts):
            return torch.tensor([[float(w in t.split()) for w in self.vocab] for t in texts])

        def null_embedding(self):
            return torch.zeros(3)

    table = TextTable(Words(), ["a man walks", "a man strolls", "a man jumps"], torch.device("cpu"))
    got = table.caption_residuals([["a man walks", "a man strolls"], ["a man jumps"]])
    # one group of two (the single caption has no spread): +-(1, -1, 0) / 2, times sqrt(2)
    expected = torch.tensor([[-0.5, 0.5, 0.0], [0.5, -0.5, 0.0]]) * 2 ** 0.5
    torch.testing.assert_close(got, expected)
    import pytest
    with pytest.raises(MlctError, match="two or more captions"):
        table.caption_residuals([["a man jumps"]])
