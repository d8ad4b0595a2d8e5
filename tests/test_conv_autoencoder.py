"""The convolutional autoencoder (ae.architecture: conv) keeps MotionAutoencoder's contract."""

from __future__ import annotations

import pytest
import torch

from mlct.config import load_config, config_from_dict
from mlct.nn.build import build_autoencoder
from mlct.nn import Latent, lengths_to_mask
from mlct.nn.autoencoder import MotionAutoencoder
from mlct.nn.conv_autoencoder import ConvMotionAutoencoder

D = 12
LENGTHS = torch.tensor([40, 60, 7])


def _ae(latent_type: str = "quantized") -> ConvMotionAutoencoder:
    torch.manual_seed(0)
    return ConvMotionAutoencoder(D, latent_type=latent_type, n_tokens=3, latent_dim=16,
                                 channels=24, max_len=60)


def _batch() -> torch.Tensor:
    torch.manual_seed(1)
    return torch.randn(3, 60, D)


@pytest.mark.parametrize("latent_type", ["quantized", "vae", "plain"])
def test_shapes_zero_padding_and_gradients(latent_type: str) -> None:
    ae = _ae(latent_type)
    recon, lat = ae(_batch(), LENGTHS)
    assert isinstance(lat, Latent) and lat.z.shape == (3, 3, 16) and recon.shape == (3, 60, D)
    valid = lengths_to_mask(LENGTHS, 60)
    assert torch.all(recon[~valid] == 0) and torch.all(recon[valid].abs().sum(-1) > 0)
    assert ae.decode(lat.z, torch.tensor([5, 7, 3])).shape == (3, 7, D)
    with pytest.raises(ValueError):
        ae.decode(lat.z, LENGTHS, max_len=61)
    (recon.square().mean() + (lat.kl if lat.kl is not None else 0.0)).backward()
    missing = [n for n, p in ae.named_parameters() if p.grad is None or p.grad.abs().sum() == 0]
    assert not missing, missing
    if latent_type == "quantized":
        k = lat.z * 1000
        torch.testing.assert_close(k, k.round(), rtol=0, atol=1e-3)
        assert lat.z.abs().max() <= 1.0


def test_encoder_ignores_padding_and_decoder_ignores_padding_length() -> None:
    ae = _ae("plain").eval()
    x = _batch()
    z = ae.encode(x, LENGTHS).z
    x2 = x.clone()
    valid = lengths_to_mask(LENGTHS, 60)
    x2[~valid] = 1e3 * torch.randn(int((~valid).sum()), D)
    torch.testing.assert_close(ae.encode(x2, LENGTHS).z, z, rtol=0, atol=1e-5)
    torch.testing.assert_close(ae.encode(x[:1, :40], LENGTHS[:1]).z[0], z[0])
    # a frame's output depends on the latent and the frame, not on how far the batch is padded
    torch.testing.assert_close(ae.decode(z, LENGTHS)[:, :7],
                               ae.decode(z, torch.tensor([7, 7, 7])), rtol=1e-5, atol=1e-5)


def test_config_builds_either_architecture_and_rejects_unknown() -> None:
    config = load_config("tiny").to_dict()
    assert isinstance(build_autoencoder(config_from_dict(config), D), MotionAutoencoder)
    config["ae"]["architecture"] = "conv"
    assert isinstance(build_autoencoder(config_from_dict(config), D), ConvMotionAutoencoder)
    config["ae"]["architecture"] = "lstm"
    with pytest.raises(Exception, match="architecture"):
        config_from_dict(config)


def test_frame_upsampler_reaches_every_frame_and_trains() -> None:
    torch.manual_seed(0)
    ae = MotionAutoencoder(D, n_tokens=2, latent_dim=16, layers=1, heads=2, ff_dim=32,
                           dropout=0.0, max_len=60, frame_upsampler=True)
    recon, lat = ae(_batch(), LENGTHS)
    recon.square().mean().backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in ae.upsampler.parameters())
    # another latent changes every valid frame, not only through attention to the tokens
    other = ae.decode(lat.z.roll(1, dims=0), LENGTHS)
    valid = lengths_to_mask(LENGTHS, 60)
    assert torch.all((other - recon)[valid].abs().sum(-1) > 0)


def test_arm_columns_are_the_arm_joints_positions_rotations_and_velocities() -> None:
    from mlct.motion.features import arm_feature_columns
    from mlct.motion.skeleton import FeatureLayout

    columns = arm_feature_columns(263)
    groups = FeatureLayout(22).groups
    # 8 arm joints (collars, shoulders, elbows, wrists) x (3 positions + 6 rotation + 3 velocity)
    assert len(columns) == 8 * 12 == len(set(columns))
    left_wrist = 20  # its root-relative position and velocity columns
    assert {groups["ric"].start + 3 * (left_wrist - 1) + i for i in range(3)} <= set(columns)
    assert {groups["local_velocity"].start + 3 * left_wrist + i for i in range(3)} <= set(columns)
    pelvis_height, left_knee = groups["root_height"].start, groups["ric"].start + 3 * 3
    assert pelvis_height not in columns and left_knee not in columns
    assert len(arm_feature_columns(251)) == 6 * 12  # KIT: shoulders, elbows, wrists


def test_arm_tokens_encode_and_decode_the_arms_alone() -> None:
    """ae.arm_tokens: the last token sees only the arm features, and reaches only them; the
    contract (shapes, zero padding) is kept."""
    from mlct.motion.features import arm_feature_columns

    torch.manual_seed(0)
    columns = arm_feature_columns(263)
    body = [c for c in range(263) if c not in columns]
    # plain latent: the quantizer's 1e-3 grid would hide an untrained encoder's small changes
    ae = ConvMotionAutoencoder(263, latent_type="plain", n_tokens=3, latent_dim=8, channels=16,
                               max_len=60, arm_tokens=1, arm_channels=8,
                               arm_columns=columns).eval()
    x = torch.randn(3, 60, 263)
    with torch.no_grad():
        z = ae.encode(x, LENGTHS).z
        moved = x.clone()
        moved[..., body] += 1.0
        torch.testing.assert_close(ae.encode(moved, LENGTHS).z[:, 2], z[:, 2])
        moved[..., columns] += 1.0
        assert not torch.allclose(ae.encode(moved, LENGTHS).z[:, 2], z[:, 2])
        out = ae.decode(z, LENGTHS)
        other = z.clone()
        other[:, 2] = -other[:, 2]
        changed = (ae.decode(other, LENGTHS) - out).abs().amax(dim=(0, 1))
        assert changed[body].max() == 0 and changed[columns].max() > 0
        assert torch.all(out[~lengths_to_mask(LENGTHS, 60)] == 0)
        # each decoder's features land in their own columns, in order
        body_out = ae._decode_part(z[:, :2], ae.from_tokens, ae.decoder).transpose(1, 2)[:, :60]
        arm_out = ae._decode_part(z[:, 2:], ae.arm_from_tokens,
                                  ae.arm_decoder).transpose(1, 2)[:, :60]
        valid = lengths_to_mask(LENGTHS, 60)
        torch.testing.assert_close(out[..., body][valid], body_out[valid])
        torch.testing.assert_close(out[..., columns][valid], arm_out[valid])
    with pytest.raises(ValueError, match="arm_tokens"):
        ConvMotionAutoencoder(263, n_tokens=2, arm_tokens=2, arm_columns=columns)
    with pytest.raises(ValueError, match="VAE"):
        ConvMotionAutoencoder(263, latent_type="vae", arm_tokens=1, arm_columns=columns)


def test_config_arm_tokens_needs_the_conv_architecture() -> None:
    from mlct.errors import MlctError

    config = load_config("tiny").to_dict()
    config["ae"].update(architecture="conv", arm_tokens=1, n_tokens=2, latent_dim=8, channels=8)
    ae = build_autoencoder(config_from_dict(config, "test"), 263)
    assert ae.arm_tokens == 1 and len(ae.arm_columns) == 96
    config["ae"]["architecture"] = "transformer"
    with pytest.raises(MlctError, match="arm_tokens needs"):
        build_autoencoder(config_from_dict(config, "test"), 263)
    config["ae"].update(architecture="conv", arm_tokens=2)
    with pytest.raises(MlctError, match="ae: arm_tokens"):
        build_autoencoder(config_from_dict(config, "test"), 263)


def test_bottleneck_mlp_between_grid_and_tokens() -> None:
    """ae.bottleneck=h: an MLP of hidden width h beside each Linear, starting at zero (so the
    model starts as the plain one); the contract is unchanged and every weight learns; the
    transformer refuses it by name."""
    torch.manual_seed(0)
    ae = ConvMotionAutoencoder(D, n_tokens=3, latent_dim=16, channels=24, max_len=60,
                               bottleneck=32)
    assert (ae.to_tokens.hidden.out_features, ae.to_tokens.out.out_features) == (32, 48)
    assert (ae.from_tokens.hidden.in_features, ae.from_tokens.hidden.out_features) == (48, 32)
    torch.manual_seed(0)
    plain = ConvMotionAutoencoder(D, n_tokens=3, latent_dim=16, channels=24, max_len=60)
    plain.to_tokens.load_state_dict(ae.to_tokens.linear.state_dict())
    plain.from_tokens.load_state_dict(ae.from_tokens.linear.state_dict())
    plain.encoder.load_state_dict(ae.encoder.state_dict())
    plain.decoder.load_state_dict(ae.decoder.state_dict())
    plain.eval(), ae.eval()
    assert torch.allclose(plain(_batch(), LENGTHS)[0], ae(_batch(), LENGTHS)[0])
    ae.train()
    recon, lat = ae(_batch(), LENGTHS)
    assert lat.z.shape == (3, 3, 16) and recon.shape == (3, 60, D)
    assert torch.all(recon[~lengths_to_mask(LENGTHS, 60)] == 0)
    recon.square().mean().backward()
    # the hidden layers get gradient once their zero output layer has moved: not on step one
    silent = [n for n, p in ae.named_parameters() if p.grad is None or p.grad.abs().sum() == 0]
    assert sorted(silent) == ["from_tokens.hidden.bias", "from_tokens.hidden.weight",
                              "to_tokens.hidden.bias", "to_tokens.hidden.weight"]
    config = config_from_dict({"ae": {"architecture": "conv", "bottleneck": 64}})
    assert build_autoencoder(config, D).bottleneck == 64
    from mlct.errors import MlctError
    with pytest.raises(MlctError, match="ae.bottleneck needs ae.architecture=conv"):
        build_autoencoder(config_from_dict({"ae": {"bottleneck": 64}}), D)


def test_temporal_tokens_each_hold_their_own_stretch_of_time() -> None:
    """ae.temporal: token i encodes and draws only its stretch of the clip; changing the motion
    late in the clip leaves the first token as it was, and the first token draws no late frame."""
    torch.manual_seed(0)
    ae = ConvMotionAutoencoder(D, latent_type="plain", n_tokens=3, latent_dim=16, channels=24,
                               max_len=96, temporal=True).eval()  # 12 cells, 4 a token
    x = torch.randn(1, 96, D)
    lengths = torch.tensor([96])
    late = x.clone()
    late[:, 80:] += 1.0  # frames 80.. sit in cells 10-11: the third token's stretch
    z, z_late = ae.encode(x, lengths).z, ae.encode(late, lengths).z
    assert z.shape == (1, 3, 16)
    # the encoder's convolutions reach a few frames back, not a whole token's stretch
    assert torch.allclose(z[:, 0], z_late[:, 0]) and not torch.allclose(z[:, 2], z_late[:, 2])
    moved = z.clone()
    moved[:, 0] += 1.0
    out, out_moved = ae.decode(z, lengths), ae.decode(moved, lengths)
    changed = (out - out_moved).abs().amax(dim=(0, 2)) > 0  # (T,) frames the first token drew
    assert changed[:32].all() and not changed[48:].any()
    recon, _ = ae.train()(x, lengths)
    recon.square().mean().backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in ae.parameters())
    with pytest.raises(ValueError, match="temporal tokens go without"):
        ConvMotionAutoencoder(D, n_tokens=3, latent_dim=16, max_len=96, temporal=True,
                              bottleneck=8)


@pytest.mark.parametrize("temporal", [False, True])
def test_a_short_clip_decodes_only_its_cells_and_the_same_frames(temporal: bool) -> None:
    """decode() runs the convolutions over the cells t frames need plus DECODE_MARGIN; the
    frames are those of the whole grid (the margin covers the receptive field: bitwise on this
    repository's CPUs, float rounding allowed here), and one cell less of margin would change
    them (the check can fail)."""
    torch.manual_seed(0)
    kwargs = {"temporal": True} if temporal else {"arm_tokens": 1, "arm_channels": 16,
                                                  "arm_columns": [3, 4, 5, 10]}
    ae = ConvMotionAutoencoder(20, "plain", n_tokens=3, latent_dim=8, channels=16, max_len=196,
                               **kwargs).eval()
    z = torch.rand(2, 3, 8) * 2 - 1
    with torch.no_grad():
        whole = ae.decode(z, torch.tensor([196, 196]), 196)
        for t in (1, 7, 8, 9, 60, 100, 150, 190, 196):
            lengths = torch.tensor([t, max(1, t // 2)])
            cut = ae.decode(z, lengths, t)
            masked = whole[:, :t].masked_fill(~lengths_to_mask(lengths, t)[..., None], 0.0)
            torch.testing.assert_close(cut, masked, rtol=0, atol=1e-6, msg=str(t))
        seen = []
        assert ae.decode_margin == 2  # DECODE_MARGIN at the default 3 stages
        ae.decode_margin = 1
        for t in (60, 100):
            gap = (ae.decode(z, torch.tensor([t, t]), t) - whole[:, :t]).abs().max()
            seen.append(bool(gap < 1e-6))
        assert not all(seen)


@pytest.mark.parametrize("stages", [2, 4])
def test_fewer_or_more_stages_change_the_grid_and_keep_the_contract(stages: int) -> None:
    """ae.stages sets the frames per grid cell (2 ** stages); any clip length round-trips and
    a short clip decodes the frames of the whole grid over its cells and the margin."""
    torch.manual_seed(0)
    ae = ConvMotionAutoencoder(20, "plain", n_tokens=3, latent_dim=8, channels=16, max_len=196,
                               stages=stages).eval()
    assert ae.coarse == -(-196 // 2**stages)
    x = torch.randn(2, 196, 20)
    with torch.no_grad():
        z = ae.encode(x, torch.tensor([196, 50])).z
        assert z.shape == (2, 3, 8)
        whole = ae.decode(z, torch.tensor([196, 196]), 196)
        assert whole.shape == (2, 196, 20)
        for t in (9, 60, 150):
            cut = ae.decode(z, torch.tensor([t, t]), t)
            torch.testing.assert_close(cut, whole[:, :t], rtol=0, atol=1e-6, msg=str(t))
    with pytest.raises(ValueError, match="stages"):
        ConvMotionAutoencoder(20, n_tokens=3, latent_dim=8, stages=5)
