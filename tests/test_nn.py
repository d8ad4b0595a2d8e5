"""Networks of stages 1 and 2: shapes, masking, latent types, gradients, sizes, save/load."""

from __future__ import annotations

import io

import pytest
import torch

from mlct.nn import Denoiser, Latent, MotionAutoencoder, SkipTransformer, lengths_to_mask

D = 11  # tiny feature dimension
TINY_AE = dict(n_tokens=3, latent_dim=32, levels=1000, layers=3, heads=4, ff_dim=64, max_len=60)
TINY_DEN = dict(latent_dim=32, n_tokens=3, text_dim=24, width=32, layers=3, heads=4, ff_dim=64,
                time_embed_dim=16)
LENGTHS = torch.tensor([40, 60, 7])


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """Tiny tensors: one intra-op thread avoids OpenMP spin-waits on a busy machine."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def _ae(latent_type: str = "quantized", seed: int = 0) -> MotionAutoencoder:
    torch.manual_seed(seed)
    return MotionAutoencoder(D, latent_type=latent_type, **TINY_AE)


def _den(seed: int = 0) -> Denoiser:
    torch.manual_seed(seed)
    return Denoiser(**TINY_DEN)


def _batch(seed: int = 1) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.randn(len(LENGTHS), int(LENGTHS.max()), D, generator=g)


def _n_params(m: torch.nn.Module) -> int:
    return sum(p.numel() for p in m.parameters())


# ----------------------------------------------------------------------------- masks


def test_lengths_to_mask() -> None:
    m = lengths_to_mask(torch.tensor([2, 0, 3]), 4)
    assert m.dtype == torch.bool and m.tolist() == [
        [True, True, False, False], [False] * 4, [True, True, True, False]]
    assert lengths_to_mask(torch.tensor([1, 3])).shape == (2, 3)
    with pytest.raises(ValueError):
        lengths_to_mask(torch.tensor([5]), 4)


# ----------------------------------------------------------------------------- skip transformer


def test_skip_transformer_rejects_even_layers_and_bad_activation() -> None:
    with pytest.raises(ValueError, match="odd"):
        SkipTransformer(32, 4, 4, 64, 0.0)
    with pytest.raises(ValueError, match="activation"):
        SkipTransformer(32, 3, 4, 64, 0.0, activation="swish")


def test_skip_transformer_padding_and_cond() -> None:
    torch.manual_seed(0)
    net = SkipTransformer(32, 5, 4, 64, 0.1).eval()
    assert len(net.input_blocks) == 2 and len(net.output_blocks) == 2
    x = torch.randn(2, 9, 32)
    pad = torch.zeros(2, 9, dtype=torch.bool)
    pad[0, 5:] = True
    y = net(x, pad)
    x2 = x.clone()
    x2[0, 5:] = 100.0 * torch.randn(4, 32)  # change only padded content
    y2 = net(x2, pad)
    assert y.shape == (2, 9, 32)
    torch.testing.assert_close(y2[0, :5], y[0, :5], rtol=0, atol=1e-6)
    torch.testing.assert_close(y2[1], y[1], rtol=0, atol=1e-6)
    cond = torch.randn(2, 1, 32)
    assert not torch.allclose(net(x, pad, cond=cond), y)
    per_block = [torch.zeros(2, 9, 32)] * 5
    torch.testing.assert_close(net(x, pad, cond=per_block), y)
    with pytest.raises(ValueError, match="one tensor per block"):
        net(x, pad, cond=per_block[:2])


# ----------------------------------------------------------------------------- autoencoder


def test_unknown_latent_type() -> None:
    with pytest.raises(ValueError, match="quantized.*vae.*plain"):
        MotionAutoencoder(D, latent_type="vq")


@pytest.mark.parametrize("latent_type", ["quantized", "vae", "plain"])
def test_ae_shapes_and_zero_padding(latent_type: str) -> None:
    ae = _ae(latent_type)
    x = _batch()
    recon, lat = ae(x, LENGTHS)
    assert isinstance(lat, Latent)
    assert ae.latent_shape == (3, 32)
    assert recon.shape == x.shape and lat.z.shape == (3, 3, 32) and lat.z_e.shape == (3, 3, 32)
    valid = lengths_to_mask(LENGTHS, 60)
    assert torch.all(recon[~valid] == 0)
    assert torch.all(recon[valid].abs().sum(-1) > 0)
    assert ae.decode(lat.z, LENGTHS).shape == (3, 60, D)
    assert ae.decode(lat.z, torch.tensor([5, 7, 3])).shape == (3, 7, D)
    assert ae.decode(lat.z, torch.tensor([5, 7, 3]), max_len=20).shape == (3, 20, D)
    with pytest.raises(ValueError):
        ae.decode(lat.z, LENGTHS, max_len=61)


def test_encoder_ignores_padded_content() -> None:
    ae = _ae("plain").eval()
    x = _batch()
    z = ae.encode(x, LENGTHS).z
    x2 = x.clone()
    valid = lengths_to_mask(LENGTHS, 60)
    x2[~valid] = 1e3 * torch.randn(int((~valid).sum()), D)
    torch.testing.assert_close(ae.encode(x2, LENGTHS).z, z, rtol=0, atol=1e-5)
    # the amount of padding does not change the latent either
    z40 = ae.encode(x[:1, :40], LENGTHS[:1]).z
    torch.testing.assert_close(z40[0], z[0], rtol=1e-5, atol=1e-5)
    # inference (no_grad takes PyTorch's fused encoder-layer path) agrees
    with torch.inference_mode():
        torch.testing.assert_close(ae.encode(x2, LENGTHS).z, z, rtol=1e-5, atol=1e-5)


def test_decoder_ignores_padding_length() -> None:
    ae = _ae("quantized").eval()
    z = ae.encode(_batch(), LENGTHS).z
    short = ae.decode(z, LENGTHS)  # T = 60
    long = ae.decode(z, LENGTHS[[2]].expand(3), max_len=60)  # all length 7, padded to 60
    tight = ae.decode(z, LENGTHS[[2]].expand(3))  # all length 7, T = 7
    torch.testing.assert_close(long[:, :7], tight, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(short[2, :7], tight[2], rtol=1e-5, atol=1e-5)  # same length 7
    assert not torch.allclose(short[0, :7], tight[0])  # length 40 vs 7: the mask is used
    with torch.inference_mode():
        torch.testing.assert_close(ae.decode(z, LENGTHS), short, rtol=1e-5, atol=1e-5)


def test_quantized_latent_on_grid_and_gradient_reaches_encoder() -> None:
    ae = _ae("quantized")
    recon, lat = ae(_batch(), LENGTHS)
    k = lat.z * 1000
    torch.testing.assert_close(k, k.round(), rtol=0, atol=1e-3)
    assert lat.z.abs().max() <= 1.0 and lat.kl is None
    torch.testing.assert_close(lat.z, torch.round(1000 * torch.tanh(lat.z_e)) / 1000)
    recon.square().sum().backward()
    assert ae.enc_in.weight.grad is not None and ae.enc_in.weight.grad.abs().sum() > 0
    assert ae.enc_tokens.grad.abs().sum() > 0


def test_vae_kl_and_eval_determinism() -> None:
    ae = _ae("vae")
    assert ae.enc_tokens.shape[1] == 6  # means and log-variances
    x = _batch()
    _, lat = ae(x, LENGTHS)
    assert lat.kl is not None and lat.kl.ndim == 0 and torch.isfinite(lat.kl) and lat.kl >= 0
    ae.eval()
    a, b = ae.encode(x, LENGTHS), ae.encode(x, LENGTHS)
    torch.testing.assert_close(a.z, b.z, rtol=0, atol=0)
    torch.testing.assert_close(a.z, a.z_e)  # eval: the mean


def test_plain_latent_is_encoder_output() -> None:
    ae = _ae("plain")
    _, lat = ae(_batch(), LENGTHS)
    assert lat.kl is None and lat.z is lat.z_e


@pytest.mark.parametrize("latent_type", ["quantized", "vae", "plain"])
def test_ae_every_parameter_gets_gradient(latent_type: str) -> None:
    ae = _ae(latent_type)
    recon, lat = ae(_batch(), LENGTHS)
    loss = recon.square().mean() + (lat.kl if lat.kl is not None else 0.0)
    loss.backward()
    missing = [n for n, p in ae.named_parameters() if p.grad is None or p.grad.abs().sum() == 0]
    assert not missing, missing
    if latent_type == "vae":  # the log-variance tokens are used
        assert ae.enc_tokens.grad[0, 3:].abs().sum() > 0


# ----------------------------------------------------------------------------- denoiser


def test_denoiser_shape_and_dependence_on_t_and_text() -> None:
    den = _den().eval()
    g = torch.Generator().manual_seed(2)
    x = torch.randn(4, 3, 32, generator=g)
    text = torch.randn(4, 24, generator=g)
    t = torch.full((4,), 0.5)
    out = den(x, t, text)
    assert out.shape == (4, 3, 32) and torch.isfinite(out).all()
    assert (den(x, torch.full((4,), 0.1), text) - out).abs().max() > 1e-4
    assert (den(x, t, torch.randn(4, 24, generator=g)) - out).abs().max() > 1e-4
    torch.testing.assert_close(den(x, 0.5, text), out)  # scalar t broadcasts
    with pytest.raises(ValueError):
        den(x, t, text[:, :10])


def test_condition_on_every_token_reaches_the_latent_tokens_without_attention() -> None:
    # With attention zeroed out, a latent token can learn of the text only if the condition
    # is added to it directly: the authors' layout (condition token only) then ignores the text.
    g = torch.Generator().manual_seed(3)
    x, t = torch.randn(2, 3, 32, generator=g), torch.full((2,), 0.5)
    text_a, text_b = torch.randn(2, 24, generator=g), torch.randn(2, 24, generator=g)
    for every, depends in ((False, False), (True, True)):
        torch.manual_seed(0)
        den = Denoiser(latent_dim=32, n_tokens=3, text_dim=24, width=32, layers=3, heads=4,
                       ff_dim=64, dropout=0.0, condition_all_tokens=every).eval()
        for layer in den.backbone.modules():
            if isinstance(layer, torch.nn.MultiheadAttention):
                torch.nn.init.zeros_(layer.out_proj.weight)
                torch.nn.init.zeros_(layer.out_proj.bias)
        with torch.no_grad():
            moved = (den(x, t, text_a) - den(x, t, text_b)).abs().max()
        assert (moved > 1e-4) == depends, (every, float(moved))


def test_denoiser_every_parameter_gets_gradient() -> None:
    den = _den()
    out = den(torch.randn(2, 3, 32), torch.rand(2), torch.randn(2, 24))
    out.square().mean().backward()
    missing = [n for n, p in den.named_parameters() if p.grad is None or p.grad.abs().sum() == 0]
    assert not missing, missing


# ----------------------------------------------------------------------------- sizes, seeds, io


def _layer_params(d: int, ff: int) -> int:
    """Post-norm encoder layer: qkv + out projections, two FF linears, two LayerNorms."""
    return 4 * d * d + 4 * d + 2 * d * ff + ff + d + 4 * d


def _skip_params(d: int, ff: int, layers: int) -> int:
    return layers * _layer_params(d, ff) + (layers - 1) // 2 * (2 * d * d + d) + 2 * d


def test_paper_size_parameter_counts() -> None:
    ae = MotionAutoencoder(263)  # HumanML3D, Sec. 5: 7 layers, d = 256, n = 3
    d, f, n, t = 256, 263, 3, 196
    expected_ae = (
        (f * d + d) + n * d + (n + t) * d + _skip_params(d, 1024, 7)  # encoder
        + (n + t) * d + _skip_params(d, 1024, 7) + (d * f + f) + (f * f + f)  # decoder + head
    )
    assert _n_params(ae) == expected_ae == 12_152_895
    den = Denoiser(text_dim=768)  # CLIP ViT-L/14 pooled, 11 layers, width 512
    w, L = 512, 11
    expected_den = (
        (d * w + w) + (1 + n) * w + L * (256 * w + w) + 2 * 768 + L * (768 * w + w)
        + _skip_params(w, 2048, L) + (w * d + d) + (d * d + d)
    )  # 2 * 768: the LayerNorm on the text embedding
    assert _n_params(den) == expected_den == 43_411_968


def test_seeded_construction_is_deterministic() -> None:
    a, b = _ae("vae", seed=3), _ae("vae", seed=3)
    for (na, pa), (_, pb) in zip(a.state_dict().items(), b.state_dict().items()):
        assert torch.equal(pa, pb), na
    x = _batch()
    torch.manual_seed(7)
    ra, _ = a(x, LENGTHS)
    torch.manual_seed(7)
    rb, _ = b(x, LENGTHS)
    torch.testing.assert_close(ra, rb, rtol=0, atol=0)


@pytest.mark.parametrize("kind", ["ae", "denoiser"])
def test_state_dict_round_trip(kind: str) -> None:
    src = _ae("quantized", seed=4) if kind == "ae" else _den(seed=4)
    dst = _ae("quantized", seed=5) if kind == "ae" else _den(seed=5)
    want = src.state_dict()
    # the two differ before loading, so that equal values after it are the load's doing
    assert any(not torch.equal(v, dst.state_dict()[k]) for k, v in want.items())
    buf = io.BytesIO()
    torch.save(want, buf)
    buf.seek(0)
    dst.load_state_dict(torch.load(buf, weights_only=True))
    got = dst.state_dict()
    assert list(got) == list(want)  # the same entries, in the same order
    for key, value in want.items():  # every parameter and buffer: value, dtype and shape
        assert got[key].dtype == value.dtype and torch.equal(got[key], value), key
    src.eval(), dst.eval()
    if kind == "ae":
        x = _batch()
        torch.testing.assert_close(dst(x, LENGTHS)[0], src(x, LENGTHS)[0], rtol=0, atol=0)
    else:
        args = (torch.randn(2, 3, 32), torch.rand(2), torch.randn(2, 24))
        torch.testing.assert_close(dst(*args), src(*args), rtol=0, atol=0)


def test_denoiser_attends_over_token_states() -> None:
    """text_tokens > 0: a change in one token row alone (the pooled vector kept) changes F."""
    from mlct.nn.inference import for_inference

    torch.manual_seed(0)
    k, dim = 4, 16
    den = Denoiser(latent_dim=8, n_tokens=2, text_dim=(1 + k) * dim, width=32, layers=3,
                   heads=4, ff_dim=64, dropout=0.0, text_tokens=k, text_heads=2)
    text = torch.randn(2, 1 + k, dim)
    text[:, 3:] = 0  # two token rows, then padding
    x, t = torch.randn(2, 2, 8), torch.tensor([0.3, 0.7])
    out = den(x, t, text.flatten(1))
    out.square().sum().backward()
    assert den.text_query.grad.abs().sum() > 0
    assert all(p.grad is not None for p in den.text_attention.parameters())
    den.eval()
    with torch.no_grad():
        base = den(x, t, text.flatten(1))
        side = text.clone()
        side[:, 2] = torch.randn(2, dim)  # one token differs, as "left" / "right" do
        assert (den(x, t, side.flatten(1)) - base).abs().max() > 1e-3
        fast = for_inference(den, torch.float32)
        torch.testing.assert_close(fast(x, t, text.flatten(1)), base, rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="text_dim"):
        Denoiser(latent_dim=8, n_tokens=2, text_dim=51, text_tokens=4)
