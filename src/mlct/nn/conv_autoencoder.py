"""A 1-D convolutional motion autoencoder around the paper's latent (ours; ``ae.architecture: conv``).

Same contract as `MotionAutoencoder`: frames (B, T, D) -> n latent tokens (B, n, d), quantized
(Eq. 8), VAE or plain -> frames, so stage 2 and every sampler are unchanged. Only E and D differ:
- E: the frames (padding zeroed, the validity mask as one more channel) through a Conv1d stem and
  three stride-2 stages (``ae.stages``; T/8 steps of `channels`), flattened over a fixed
  ``max_len / 8`` grid, then one Linear to the n x d tokens (2n for the VAE);
- D: one Linear from the flat latent back to that coarse grid, as many nearest-upsample x2
  stages of two Conv1d each, a Conv1d to D features; frames past the length are set to 0.
Time is absolute: frame k of any clip sits at grid cell k // 8, as in the transformer's
positional embeddings.

Optionally (``ae.arm_tokens`` = a > 0) the arms get their own pair: the features of the collar,
shoulder, elbow and wrist joints (their root-relative positions, rotations and velocities;
`arm_feature_columns`) go through a second E of ``arm_channels`` to the last a tokens, and a
second D draws them from those tokens alone; the first E still sees every feature and its D
draws the rest from the first n - a tokens.
Why: of the motions that lay an arm action over a gait, the shared pair drew the gait and only
the family's average arm (claps that never meet) on the training split as on the test split;
neither a wider decoder nor oversampling those motions moved it (docs/training.md). Root-relative
arm features of a clap are the same over a walk
as standing still, so a pair that sees only them has one motion to draw, not a combination.

Optionally (``ae.bottleneck`` = h > 0) the maps between the coarse grid and the tokens are
one Linear each plus a two-layer MLP of hidden width h beside it. Why: with a Linear, the decoder's
coarse grid is a linear function of the 192 latent numbers, so an event must have its own
latent directions at each time it may happen, and the gait and an arm's oscillation compete for
them; a hidden layer can place "a clap at time t" from a few numbers.

Optionally (``ae.temporal``) the tokens are a time series instead: token i encodes and draws
only the i-th stretch of the grid (a Conv1d / ConvTranspose1d of stride cells / n in place of
the Linear maps), as the temporal latents of the motion VQ-VAEs are. Why: with a global
latent, an arm's oscillation over a gait must find latent directions of its own for each time
it may happen; a token of its own stretch says what happens there, gait and arms together.

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

STAGES = 3  # stride-2 stages of the encoder (and 2x upsampling ones of the decoder)
FACTOR = 2**STAGES  # frames per grid cell at the default stages
# Grid cells past a clip's last one that still reach its frames through the decoder's
# convolutions (3 x 2 of kernel 3 after each 2x upsampling, then one more): with 2 more the
# frames are bitwise those of the whole grid, with 1 they differ by up to 1.1
# (tests/test_conv_autoencoder.py)
DECODE_MARGIN = 2


def _stage(channels: int, down: bool) -> list[nn.Module]:
    resample: nn.Module = (nn.Conv1d(channels, channels, 4, stride=2, padding=1) if down
                           else nn.Upsample(scale_factor=2, mode="nearest"))
    layers = [resample, nn.Conv1d(channels, channels, 3, padding=1), nn.GELU()]
    if down:
        layers.insert(1, nn.GELU())
    else:
        layers += [nn.Conv1d(channels, channels, 3, padding=1), nn.GELU()]
    return layers


class _LinearPlusMLP(nn.Module):
    """y = Linear(x) + W2 GELU(W1 x), W2 starting at zero: the map starts as the plain Linear
    (a two-layer MLP alone trained 3x slower: val feature loss 0.206 against 0.070 at step
    4,000) and adds what a hidden layer can express."""

    def __init__(self, inputs: int, outputs: int, hidden: int) -> None:
        super().__init__()
        self.linear = nn.Linear(inputs, outputs)
        self.hidden = nn.Linear(inputs, hidden)
        self.out = nn.Linear(hidden, outputs)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, x: Tensor) -> Tensor:
        return self.linear(x) + self.out(nn.functional.gelu(self.hidden(x)))


class _GridToTimeTokens(nn.Module):
    """(B, channels x cells) -> (B, n x d): token i encodes the i-th stretch of ceil(cells / n)
    grid cells (a strided Conv1d), so each token holds its own part of the clip."""

    def __init__(self, channels: int, cells: int, tokens: int, dim: int) -> None:
        super().__init__()
        self.channels, self.cells, self.span = channels, cells, -(-cells // tokens)
        self.pad = self.span * tokens - cells
        self.conv = nn.Conv1d(channels, dim, self.span, stride=self.span)

    def forward(self, flat: Tensor) -> Tensor:
        h = nn.functional.pad(flat.view(flat.shape[0], self.channels, self.cells), (0, self.pad))
        return self.conv(h).transpose(1, 2).flatten(1)  # (B, n * d), token-major


class _TimeTokensToGrid(nn.Module):
    """(B, n x d) -> (B, channels x cells): token i draws the i-th stretch of the grid."""

    def __init__(self, channels: int, cells: int, tokens: int, dim: int) -> None:
        super().__init__()
        self.cells, self.tokens, self.dim, self.span = cells, tokens, dim, -(-cells // tokens)
        self.conv = nn.ConvTranspose1d(dim, channels, self.span, stride=self.span)

    def forward(self, flat: Tensor) -> Tensor:
        z = flat.view(flat.shape[0], self.tokens, self.dim).transpose(1, 2)  # (B, d, n)
        return self.conv(z)[:, :, :self.cells].flatten(1)


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
        arm_tokens: int = 0,
        arm_channels: int = 64,
        arm_columns: list[int] | None = None,
        bottleneck: int = 0,
        temporal: bool = False,
        decoder_channels: int = 0,
        arm_decoder_channels: int = 0,
        stages: int = STAGES,
    ) -> None:
        if not 1 <= stages <= 4:
            raise ValueError(f"stages must be 1..4, got {stages}")
        if channels < 1 or arm_channels < 1:
            raise ValueError("channels and arm_channels must be >= 1")
        if arm_tokens and not 0 < arm_tokens < n_tokens:
            raise ValueError(f"arm_tokens must leave the body at least one of the {n_tokens} "
                             f"tokens, got {arm_tokens}")
        if arm_tokens and latent_type == "vae":
            raise ValueError("arm_tokens supports the quantized and plain latents, not the VAE")
        if temporal and (arm_tokens or bottleneck or latent_type == "vae"):
            raise ValueError("temporal tokens go without arm_tokens, bottleneck and the VAE")
        if arm_tokens and not arm_columns:
            raise ValueError("arm_tokens needs the arm feature columns (arm_feature_columns)")
        super().__init__(feature_dim, latent_type, n_tokens, latent_dim, levels, max_len)
        self.channels = channels
        self.bottleneck = bottleneck
        self.temporal = temporal
        self.stages, self.factor = stages, 2**stages  # frames per grid cell
        self.coarse = -(-max_len // self.factor)  # grid cells covering max_len frames
        # the decoder's reach past a clip's last cell, in frames as measured for 3 stages
        self.decode_margin = -(-DECODE_MARGIN * FACTOR // self.factor)
        self.arm_tokens = arm_tokens
        arm = sorted(set(arm_columns)) if arm_tokens and arm_columns else []
        body = sorted(set(range(feature_dim)) - set(arm))
        self.body_columns, self.arm_columns = body, arm
        if arm_tokens:  # index tensors built once, not per call; not part of the weights
            self.register_buffer("arm_index", torch.tensor(arm), persistent=False)
        # the decoders' outputs put back in feature order: runs (part, start, stop) of each
        # part's columns, in order; slices joined once are far cheaper than a gather along the
        # features (13 runs for the HumanML3D arms: 35 ms against ~5 for 64 clips on a thread)
        source = {f: (0, i) for i, f in enumerate(body)} | {f: (1, i) for i, f in enumerate(arm)}
        self.feature_runs: list[tuple[int, int, int]] = []
        for f in range(feature_dim):
            part, i = source[f]
            last = self.feature_runs[-1] if self.feature_runs else None
            if last and last[0] == part and last[2] == i:
                self.feature_runs[-1] = (part, last[1], i + 1)
            else:
                self.feature_runs.append((part, i, i + 1))
        body_tokens = n_tokens - arm_tokens
        n_enc = 2 * n_tokens if latent_type == "vae" else body_tokens

        # the body's encoder sees every feature (the arms' swing keeps time with the gait); only
        # its decoder is limited to the body's columns
        self.encoder, self.to_tokens = self._encoder(feature_dim, channels, n_enc)
        # a decoder may be narrower than its encoder (ae.decoder_channels; 0 = as wide)
        self.from_tokens, self.decoder = self._decoder(body_tokens, decoder_channels or channels,
                                                       len(body))
        if arm_tokens:
            self.arm_encoder, self.arm_to_tokens = self._encoder(len(arm), arm_channels,
                                                                 arm_tokens)
            self.arm_from_tokens, self.arm_decoder = self._decoder(arm_tokens,
                                                                   arm_decoder_channels
                                                                   or arm_channels,
                                                                   len(arm))

    def _encoder(self, features: int, channels: int, tokens: int) -> tuple[nn.Module, nn.Module]:
        stem = [nn.Conv1d(features + 1, channels, 3, padding=1), nn.GELU()]
        convs = nn.Sequential(*stem, *[m for _ in range(self.stages)
                                       for m in _stage(channels, True)])
        if self.temporal:
            return convs, _GridToTimeTokens(channels, self.coarse, tokens, self.latent_dim)
        return convs, self._grid_map(self.coarse * channels, tokens * self.latent_dim)

    def _decoder(self, tokens: int, channels: int, features: int) -> tuple[nn.Module, nn.Module]:
        convs = nn.Sequential(*[m for _ in range(self.stages) for m in _stage(channels, False)],
                              nn.Conv1d(channels, features, 3, padding=1))
        if self.temporal:
            return _TimeTokensToGrid(channels, self.coarse, tokens, self.latent_dim), convs
        return self._grid_map(tokens * self.latent_dim, self.coarse * channels), convs

    def _grid_map(self, inputs: int, outputs: int) -> nn.Module:
        """Coarse grid <-> flat tokens: one Linear, plus with ``bottleneck`` an MLP beside it."""
        if not self.bottleneck:
            return nn.Linear(inputs, outputs)
        return _LinearPlusMLP(inputs, outputs, self.bottleneck)

    def encode(self, x: Tensor, lengths: Tensor) -> Latent:
        """E: x (B, T, D) normalized features, lengths (B,) -> Latent with z (B, n, d)."""
        self._check_frames(x, lengths)
        b, t, _ = x.shape
        valid = lengths_to_mask(lengths.to(x.device), t).to(x.dtype).unsqueeze(-1)  # (B, T, 1)
        x = x * valid
        if not self.arm_tokens:
            tokens = self._encode_part(x, valid, self.encoder, self.to_tokens)  # (B, n_enc, d)
        else:
            tokens = torch.cat([
                self._encode_part(x, valid, self.encoder, self.to_tokens),
                self._encode_part(x.index_select(-1, self.arm_index), valid, self.arm_encoder,
                                  self.arm_to_tokens)], dim=1)  # (B, n, d)
        return latent_of_tokens(tokens, self.latent_type, self.n_tokens, self.levels,
                                self.training)

    def _encode_part(self, x: Tensor, valid: Tensor, convs: nn.Module, linear: nn.Module
                     ) -> Tensor:
        """x (B, T, F) zero-padded, valid (B, T, 1) -> tokens (B, k, d)."""
        h = torch.cat([x, valid], dim=-1).transpose(1, 2)  # (B, F + 1, T)
        h = nn.functional.pad(h, (0, self.coarse * self.factor - x.shape[1]))  # (B, F + 1, T')
        h = convs(h)  # (B, channels, coarse)
        return linear(h.flatten(1)).view(x.shape[0], -1, self.latent_dim)

    def decode(self, z: Tensor, lengths: Tensor, max_len: int | None = None) -> Tensor:
        """D: z (B, n, d), lengths (B,) -> (B, T, D), T = max_len or max(lengths); pads are 0."""
        self._check_latent(z)
        t = int(lengths.max()) if max_len is None else max_len
        self._check_lengths(lengths, t)
        # (B, T, F) views of the stacks' (B, F, coarse * 8): joined and ordered along the last
        # axis, which is the memory's fastest one when the stacks run channels-last (inference)
        # the convolutions run over the grid cells the t frames need and DECODE_MARGIN more (their
        # receptive field), not over all of max_len: a 5 s clip costs ~0.6 of a 9.8 s one
        # (t + 7) // 8, not -(-t // 8): traced into a graph, // truncates, and of a negative
        # number that is not the floor
        cells = min(self.coarse, (t + self.factor - 1) // self.factor + self.decode_margin)
        if not self.arm_tokens:
            out = self._decode_part(z, self.from_tokens, self.decoder, cells).transpose(1, 2)
        else:
            k = self.n_tokens - self.arm_tokens
            parts = (self._decode_part(z[:, :k], self.from_tokens, self.decoder,
                                       cells).transpose(1, 2),
                     self._decode_part(z[:, k:], self.arm_from_tokens, self.arm_decoder,
                                       cells).transpose(1, 2))
            out = torch.cat([parts[p][..., a:b] for p, a, b in self.feature_runs], dim=2)
        out = out[:, :t]  # (B, T, D)
        valid = lengths_to_mask(lengths.to(z.device), t)  # (B, T)
        return out.masked_fill(~valid.unsqueeze(-1), 0.0)  # padded frames exactly 0

    def _decode_part(self, z: Tensor, linear: nn.Module, convs: nn.Module,
                     cells: int | None = None) -> Tensor:
        """z (B, k, d) -> (B, F, cells * 8): the first `cells` grid cells (default all)."""
        h = linear(z.flatten(1)).view(z.shape[0], -1, self.coarse)
        return convs(h if cells is None else h[:, :, :cells])
