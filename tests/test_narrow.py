"""nn/narrow.py: a conv autoencoder's decoders cut to fewer channels."""

from __future__ import annotations

import pytest
import torch

from mlct.errors import MlctError
from mlct.nn.conv_autoencoder import ConvMotionAutoencoder
from mlct.nn.narrow import narrow_decoders

FEATURES, ARMS = 20, [3, 4, 5, 10, 11]


def _model(channels: int, seed: int = 0) -> ConvMotionAutoencoder:
    torch.manual_seed(seed)
    return ConvMotionAutoencoder(FEATURES, "plain", n_tokens=4, latent_dim=8, channels=16,
                                 max_len=40, arm_tokens=2, arm_channels=16, arm_columns=ARMS,
                                 decoder_channels=channels, arm_decoder_channels=channels).eval()


def _silence(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The wide decoders with only their 8 even hidden channels written to: the odd ones'
    incoming weights and biases are 0, so after GELU they are 0 and nothing downstream reads
    them. Scattered, so a cut that kept the first 8 channels would lose half the live ones."""
    state = {k: v.clone() for k, v in state.items()}
    dead = torch.arange(1, 16, 2)
    for prefix in ("", "arm_"):
        grid = state[f"{prefix}from_tokens.weight"]
        grid.view(16, -1, grid.shape[1])[dead] = 0.0  # channel c: rows c * cells ...
        state[f"{prefix}from_tokens.bias"].view(16, -1)[dead] = 0.0
        layers = sorted(int(k.split(".")[1]) for k in state
                        if k.startswith(f"{prefix}decoder.") and k.endswith(".weight"))
        for i in layers[:-1]:  # the hidden convolutions; the last one's rows are the features
            state[f"{prefix}decoder.{i}.weight"][dead] = 0.0
            state[f"{prefix}decoder.{i}.bias"][dead] = 0.0
    return state


def test_a_decoder_with_dead_channels_narrows_to_its_live_ones_exactly() -> None:
    """Only 8 of the 16 channels carry anything; narrowed to 8 the decoder must keep exactly
    those (the largest in x out norms) and draw the same features to float precision."""
    wide, narrow = _model(0), _model(8, seed=1)
    wide.load_state_dict(_silence(wide.state_dict()))
    narrow.load_state_dict(narrow_decoders(wide.state_dict(), narrow.state_dict()))
    z, lengths = torch.randn(3, 4, 8), torch.tensor([40, 33, 17])
    with torch.no_grad():
        assert torch.allclose(narrow.decode(z, lengths), wide.decode(z, lengths), atol=1e-5)
        # and the fresh narrow network is not (the check can fail)
        assert not torch.allclose(_model(8, seed=1).decode(z, lengths), wide.decode(z, lengths),
                                  atol=1e-2)


def test_narrowing_keeps_every_other_tensor_and_refuses_growth() -> None:
    wide, narrow = _model(0), _model(8, seed=1)
    out = narrow_decoders(wide.state_dict(), narrow.state_dict())
    fresh = narrow.state_dict()
    assert set(out) == set(fresh)
    assert all(v.shape == fresh[k].shape for k, v in out.items())
    # the encoders are not the decoders' business: the narrow network's own (the loop loads
    # the model's encoders over them)
    assert all(torch.equal(out[k], fresh[k]) for k in out if "encoder." in k or "to_tokens" in k)
    same = narrow_decoders(wide.state_dict(), wide.state_dict())  # same width: a copy
    assert all(torch.equal(same[k], v) for k, v in wide.state_dict().items())
    with pytest.raises(MlctError, match="it would grow"):
        narrow_decoders(narrow.state_dict(), wide.state_dict())
