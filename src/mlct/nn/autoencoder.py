"""Motion autoencoder of stage 1 (Sec. 4.1, Eq. 7-8): frames -> n latent tokens -> frames.

Facts from the MLCT authors' code (``mae_net.py``, ``block.py``), kept here:
- encoder: per-frame Linear to d, n learnable tokens in front (2n for the VAE: means then
  log-variances, as MLD), a learned positional embedding over tokens + frames (a free
  ``nn.Parameter`` initialized N(0, 1)), the skip transformer, the n token outputs = z_e;
- decoder: the queries are the decoder's own learned positional embedding (zeros + position), the
  latent tokens are added to its first n positions ("all_encoder" layout of MLD), the skip
  transformer, then a head Linear(d -> D), ReLU, Linear(D -> D) on the frame positions.
Deviations: the decoder gets the padding mask (the authors build it and do not pass it), its
padded output frames are set to 0, and it only runs over the frames requested, not always 196.

Our option ``frame_upsampler`` (off by default, as in the paper): the latent also reaches every
frame query directly, through a Linear to a coarse time axis (one step per 8 frames) and three
nearest-upsample + Conv1d stages. Why: with the latent only as n tokens in front, the decoder's
queries are the same learned positions for every motion, and on a CPU budget (a few epochs) it
learns the average pose per frame first; sharp events at varying times (a jump's flight, a swing
foot's lift) average out (docs/training.md). The conv path gives each frame a latent-dependent
signal from the first step, as the convolutional VQ-VAEs of T2M-GPT and MoMask do.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor, nn

from mlct.cuda_graphs import capturing
from mlct.nn.masks import lengths_to_mask
from mlct.nn.quantize import quantize
from mlct.nn.skip_transformer import SkipTransformer

LATENT_TYPES = ("quantized", "vae", "plain")


class Latent(NamedTuple):
    """Encoder output: ``z`` the latent stage 2 uses, ``z_e`` before quantization / sampling
    (the VAE mean), ``kl`` the mean KL(N(mu, sigma) || N(0, I)) per element (VAE only)."""

    z: Tensor  # (B, n, d)
    z_e: Tensor  # (B, n, d)
    kl: Tensor | None  # scalar


def latent_of_tokens(tokens: Tensor, latent_type: str, n_tokens: int, levels: int,
                     training: bool) -> Latent:
    """The encoder's output tokens (B, n_enc, d) -> Latent of the given type (Eq. 8 or VAE)."""
    if latent_type == "quantized":
        # fp32: under bf16 autocast the l = 1000 grid would not survive the cast back.
        return Latent(quantize(tokens.float(), levels), tokens, None)  # Eq. 8
    if latent_type == "plain":
        return Latent(tokens, tokens, None)
    mu, logvar = tokens[:, :n_tokens], tokens[:, n_tokens:]  # (B, n, d) each
    kl = 0.5 * (mu.pow(2) + logvar.exp() - 1.0 - logvar).mean()  # KL to N(0, I), per element
    z = mu + torch.exp(0.5 * logvar) * torch.randn_like(mu) if training else mu  # reparam.
    return Latent(z, mu, kl)


class _FrameUpsampler(nn.Module):
    """z (B, n, d) -> (B, T, d): a per-frame signal from the whole latent, 8x conv upsampling."""

    factor = 8

    def __init__(self, n_tokens: int, width: int, max_len: int) -> None:
        super().__init__()
        self.coarse = -(-max_len // self.factor)  # ceil: coarse steps covering max_len frames
        self.width = width
        self.project = nn.Linear(n_tokens * width, self.coarse * width)
        stages: list[nn.Module] = []
        for _ in range(3):  # 2 x 2 x 2 = factor
            stages += [nn.Upsample(scale_factor=2, mode="nearest"),
                       nn.Conv1d(width, width, kernel_size=3, padding=1), nn.GELU()]
        self.stages = nn.Sequential(*stages[:-1])  # no activation on the output

    def forward(self, z: Tensor, frames: int) -> Tensor:
        coarse = self.project(z.flatten(1)).view(z.shape[0], self.width, self.coarse)
        return self.stages(coarse)[:, :, :frames].transpose(1, 2)  # (B, frames, d)


class LatentAutoencoder(nn.Module):
    """What every stage-1 network shares: the n x d latent's arguments and shape, the argument
    checks and forward = decode(encode(x)). Subclasses define encode/decode."""

    def __init__(self, feature_dim: int, latent_type: str, n_tokens: int, latent_dim: int,
                 levels: int, max_len: int) -> None:
        super().__init__()
        if latent_type not in LATENT_TYPES:
            raise ValueError(f"latent_type must be one of {LATENT_TYPES}, got {latent_type!r}")
        if n_tokens < 1 or max_len < 1:
            raise ValueError("n_tokens and max_len must be >= 1")
        self.feature_dim = feature_dim
        self.latent_type = latent_type
        self.n_tokens = n_tokens
        self.latent_dim = latent_dim
        self.levels = levels
        self.max_len = max_len

    @property
    def latent_shape(self) -> tuple[int, int]:
        """(n, d) of the latent z."""
        return (self.n_tokens, self.latent_dim)

    def _check_lengths(self, lengths: Tensor, frames: int) -> None:
        if lengths.ndim != 1:
            raise ValueError(f"lengths must be (B,), got shape {tuple(lengths.shape)}")
        if frames > self.max_len:
            raise ValueError(f"{frames} frames exceed max_len {self.max_len}")
        if capturing():  # a CUDA graph cannot read the lengths; its caller checked them
            return
        if lengths.numel() and (int(lengths.min()) < 1 or int(lengths.max()) > frames):
            raise ValueError(f"lengths must lie in [1, {frames}]")

    def _check_frames(self, x: Tensor, lengths: Tensor) -> None:
        if x.ndim != 3 or x.shape[-1] != self.feature_dim:
            raise ValueError(f"x must be (B, T, {self.feature_dim}), got {tuple(x.shape)}")
        self._check_lengths(lengths, x.shape[1])

    def _check_latent(self, z: Tensor) -> None:
        if z.ndim != 3 or tuple(z.shape[1:]) != self.latent_shape:
            raise ValueError(
                f"z must be (B, {self.n_tokens}, {self.latent_dim}), got {tuple(z.shape)}"
            )

    def encode(self, x: Tensor, lengths: Tensor) -> Latent:
        raise NotImplementedError

    def decode(self, z: Tensor, lengths: Tensor, max_len: int | None = None) -> Tensor:
        raise NotImplementedError

    def forward(self, x: Tensor, lengths: Tensor, decode_lengths: Tensor | None = None,
                latent_noise: float = 0.0, decode_frames: int | None = None
                ) -> tuple[Tensor, Latent]:
        """Reconstruct x (B, T, D) through z: returns (D(z) (B, T, D), Latent). decode_lengths:
        decode each item to this length instead (B, T' = its max, or decode_frames where given:
        a CUDA graph cannot read the max), e.g. past the clip's end.
        latent_noise: decode z + latent_noise * N(0, I) instead of z (`ae.latent_noise`)."""
        latent = self.encode(x, lengths)
        z = latent.z + latent_noise * torch.randn_like(latent.z) if latent_noise else latent.z
        if decode_lengths is None:
            return self.decode(z, lengths, max_len=x.shape[1]), latent
        width = int(decode_lengths.max()) if decode_frames is None else decode_frames
        return self.decode(z, decode_lengths, width), latent


class MotionAutoencoder(LatentAutoencoder):
    """Transformer autoencoder E, D with a quantized (Eq. 8), VAE or plain latent of n x d."""

    def __init__(
        self,
        feature_dim: int,
        latent_type: str = "quantized",
        n_tokens: int = 3,
        latent_dim: int = 256,
        levels: int = 1000,
        layers: int = 7,
        heads: int = 8,
        ff_dim: int = 1024,
        dropout: float = 0.1,
        max_len: int = 196,
        frame_upsampler: bool = False,
    ) -> None:
        super().__init__(feature_dim, latent_type, n_tokens, latent_dim, levels, max_len)
        n_enc = 2 * n_tokens if latent_type == "vae" else n_tokens  # VAE: mean and log-variance

        # encoder E
        self.enc_in = nn.Linear(feature_dim, latent_dim)
        self.enc_tokens = nn.Parameter(torch.randn(1, n_enc, latent_dim))
        self.enc_pos = nn.Parameter(torch.randn(1, n_enc + max_len, latent_dim))
        self.encoder = SkipTransformer(latent_dim, layers, heads, ff_dim, dropout, "gelu")

        # decoder D
        self.dec_pos = nn.Parameter(torch.randn(1, n_tokens + max_len, latent_dim))
        self.decoder = SkipTransformer(latent_dim, layers, heads, ff_dim, dropout, "gelu")
        self.upsampler = _FrameUpsampler(n_tokens, latent_dim, max_len) if frame_upsampler else None
        self.head = nn.Sequential(
            nn.Linear(latent_dim, feature_dim), nn.ReLU(), nn.Linear(feature_dim, feature_dim)
        )

    def encode(self, x: Tensor, lengths: Tensor) -> Latent:
        """E: x (B, T, D) normalized features, lengths (B,) -> Latent with z (B, n, d)."""
        self._check_frames(x, lengths)
        b, t, _ = x.shape
        n_enc = self.enc_tokens.shape[1]
        valid = lengths_to_mask(lengths.to(x.device), t)  # (B, T)
        pad = torch.cat([valid.new_zeros(b, n_enc), ~valid], dim=1)  # (B, n_enc + T), tokens kept
        h = torch.cat([self.enc_tokens.expand(b, -1, -1), self.enc_in(x)], dim=1)  # (B, n_enc+T, d)
        h = h + self.enc_pos[:, : n_enc + t]
        tokens = self.encoder(h, key_padding_mask=pad)[:, :n_enc]  # (B, n_enc, d)
        return latent_of_tokens(tokens, self.latent_type, self.n_tokens, self.levels,
                                self.training)

    def decode(self, z: Tensor, lengths: Tensor, max_len: int | None = None) -> Tensor:
        """D: z (B, n, d), lengths (B,) -> (B, T, D), T = max_len or max(lengths); pads are 0."""
        self._check_latent(z)
        b, n = z.shape[0], self.n_tokens
        t = int(lengths.max()) if max_len is None else max_len
        self._check_lengths(lengths, t)
        valid = lengths_to_mask(lengths.to(z.device), t)  # (B, T)
        pad = torch.cat([valid.new_zeros(b, n), ~valid], dim=1)  # (B, n + T)
        pos = self.dec_pos[:, : n + t].expand(b, -1, -1)  # (B, n + T, d): queries = 0 + position
        frames = z.new_zeros(b, t, self.latent_dim) if self.upsampler is None else self.upsampler(z, t)
        h = pos + torch.cat([z, frames], dim=1)  # tokens in front
        h = self.decoder(h, key_padding_mask=pad)[:, n:]  # (B, T, d)
        out = self.head(h)  # (B, T, D)
        return out.masked_fill(~valid.unsqueeze(-1), 0.0)  # padded frames exactly 0
