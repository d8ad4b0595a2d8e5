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
