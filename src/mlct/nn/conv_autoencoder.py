"""A 1-D convolutional motion autoencoder around the paper's latent (ours; ``ae.architecture: conv``).

Same contract as `MotionAutoencoder`: frames (B, T, D) -> n latent tokens (B, n, d), quantized
(Eq. 8), VAE or plain -> frames, so stage 2 and every sampler are unchanged. Only E and D differ:
- E: the frames (padding zeroed, the validity mask as one more channel) through a Conv1d stem and
  three stride-2 stages (T/8 steps of `channels`), flattened over a fixed ``max_len / 8`` grid,
  then one Linear to the n x d tokens (2n for the VAE);
- D: one Linear from the flat latent back to that coarse grid, three nearest-upsample x2 stages
  of two Conv1d each, a Conv1d to D features; frames past the length are set to 0.
Time is absolute: frame k of any clip sits at grid cell k // 8, as in the transformer's
positional embeddings.

Why beside the paper's skip transformer: on this project's 2-core CPU budget (a few epochs of
the benchmark), the transformer learned the average pose per frame and drew no jump and almost no
step (pelvis-rise ratio 0.00-0.01 after 600-2,500 steps; docs/training.md). In the same wall time
this network reaches a lower reconstruction loss and draws the sharp events, because a
convolution sees each moment where it happens instead of having to learn to find it through
attention, as the convolutional motion VQ-VAEs (T2M-GPT, MoMask) do.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from mlct.nn.autoencoder import Latent, LatentAutoencoder, latent_of_tokens
from mlct.nn.masks import lengths_to_mask

FACTOR = 8  # three stride-2 stages


def _stage(channels: int, down: bool) -> list[nn.Module]:
    resample: nn.Module = (nn.Conv1d(channels, channels, 4, stride=2, padding=1) if down
                           else nn.Upsample(scale_factor=2, mode="nearest"))
    layers = [resample, nn.Conv1d(channels, channels, 3, padding=1), nn.GELU()]
    if down:
        layers.insert(1, nn.GELU())
    else:
        layers += [nn.Conv1d(channels, channels, 3, padding=1), nn.GELU()]
    return layers


class ConvMotionAutoencoder(LatentAutoencoder):
    """Convolutional E, D with a quantized (Eq. 8), VAE or plain latent of n x d."""

    def __init__(
        self,
        feature_dim: int,
        latent_type: str = "quantized",
        n_tokens: int = 3,
        latent_dim: int = 64,
        levels: int = 1000,
        channels: int = 128,
        max_len: int = 196,
    ) -> None:
        if channels < 1:
            raise ValueError("channels must be >= 1")
        super().__init__(feature_dim, latent_type, n_tokens, latent_dim, levels, max_len)
        self.channels = channels
        self.coarse = -(-max_len // FACTOR)  # grid cells covering max_len frames
        n_enc = 2 * n_tokens if latent_type == "vae" else n_tokens

        stem = [nn.Conv1d(feature_dim + 1, channels, 3, padding=1), nn.GELU()]
        self.encoder = nn.Sequential(*stem, *[m for _ in range(3) for m in _stage(channels, True)])
        self.to_tokens = nn.Linear(self.coarse * channels, n_enc * latent_dim)
        self.from_tokens = nn.Linear(n_tokens * latent_dim, self.coarse * channels)
        self.decoder = nn.Sequential(*[m for _ in range(3) for m in _stage(channels, False)],
                                     nn.Conv1d(channels, feature_dim, 3, padding=1))

    def encode(self, x: Tensor, lengths: Tensor) -> Latent:
        """E: x (B, T, D) normalized features, lengths (B,) -> Latent with z (B, n, d)."""
        self._check_frames(x, lengths)
        b, t, _ = x.shape
        valid = lengths_to_mask(lengths.to(x.device), t).to(x.dtype).unsqueeze(-1)  # (B, T, 1)
        h = torch.cat([x * valid, valid], dim=-1).transpose(1, 2)  # (B, D + 1, T)
        h = nn.functional.pad(h, (0, self.coarse * FACTOR - t))  # (B, D + 1, coarse * 8)
        h = self.encoder(h)  # (B, channels, coarse)
        tokens = self.to_tokens(h.flatten(1)).view(b, -1, self.latent_dim)  # (B, n_enc, d)
        return latent_of_tokens(tokens, self.latent_type, self.n_tokens, self.levels,
                                self.training)

    def decode(self, z: Tensor, lengths: Tensor, max_len: int | None = None) -> Tensor:
        """D: z (B, n, d), lengths (B,) -> (B, T, D), T = max_len or max(lengths); pads are 0."""
        self._check_latent(z)
        t = int(lengths.max()) if max_len is None else max_len
        self._check_lengths(lengths, t)
        h = self.from_tokens(z.flatten(1)).view(z.shape[0], self.channels, self.coarse)
        out = self.decoder(h)[:, :, :t].transpose(1, 2)  # (B, T, D)
        valid = lengths_to_mask(lengths.to(z.device), t)  # (B, T)
        return out.masked_fill(~valid.unsqueeze(-1), 0.0)  # padded frames exactly 0
