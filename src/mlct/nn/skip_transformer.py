"""Transformer with U-Net long skip connections (Sec. 5 "Implementation Details", ref. [42]).

Used by the motion encoder and decoder (Sec. 4.1) and by the consistency network F (Sec. 4.2).
Layout as in MLD's SkipTransformerEncoder and the MLCT authors' SkipEncodeTransformer:
(L-1)/2 input blocks, one middle block, (L-1)/2 output blocks; an output block takes
concat(x, skip) with the skips popped in reverse order, a Linear(2d -> d), then its layer; a final
LayerNorm. Each block is a post-norm ``torch.nn.TransformerEncoderLayer`` (batch_first), and every
weight matrix gets Xavier-uniform initialization, as both references do.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import torch
from torch import Tensor, nn

_ACTIVATIONS = ("gelu", "relu")


class SkipTransformer(nn.Module):
    """Self-attention stack with long skips; optional condition added at every block's input."""

    def __init__(
        self,
        width: int,
        layers: int,
        heads: int,
        ff_dim: int,
        dropout: float = 0.1,
        activation: str = "gelu",
    ) -> None:
        super().__init__()
        if layers < 1 or layers % 2 != 1:
            raise ValueError(f"layers must be odd and >= 1, got {layers}")
        if activation not in _ACTIVATIONS:
            raise ValueError(f"activation must be one of {_ACTIVATIONS}, got {activation!r}")
        if width % heads != 0:
            raise ValueError(f"width {width} is not divisible by heads {heads}")
        self.width = width
        self.layers = layers
        layer = nn.TransformerEncoderLayer(
            d_model=width,
            nhead=heads,
            dim_feedforward=ff_dim,
            dropout=dropout,
            activation=activation,
            batch_first=True,
            norm_first=False,  # post-norm, as MLD (normalize_before=False) and the MLCT authors
        )
        n_side = (layers - 1) // 2
        self.input_blocks = nn.ModuleList(copy.deepcopy(layer) for _ in range(n_side))
        self.middle_block = copy.deepcopy(layer)
        self.output_blocks = nn.ModuleList(copy.deepcopy(layer) for _ in range(n_side))
        self.skip_linears = nn.ModuleList(nn.Linear(2 * width, width) for _ in range(n_side))
        self.norm = nn.LayerNorm(width)
        for p in self.parameters():
            if p.dim() > 1:
                nn.init.xavier_uniform_(p)

    def _cond(self, cond: Tensor | Sequence[Tensor] | None, i: int) -> Tensor | None:
        """The condition for block i: the same tensor for all blocks, or the i-th of a list."""
        if cond is None or isinstance(cond, Tensor):
            return cond
        return cond[i]

    def forward(
        self,
        x: Tensor,
        key_padding_mask: Tensor | None = None,
        cond: Tensor | Sequence[Tensor] | None = None,
    ) -> Tensor:
        """x (B, S, d), key_padding_mask (B, S) bool True = pad (a row
        must keep one valid position), cond broadcastable to (B, S, d)
        (or a sequence of ``layers`` such tensors, one per block, in block order) -> (B, S, d)."""
        if x.ndim != 3 or x.shape[-1] != self.width:
            raise ValueError(f"x must be (B, S, {self.width}), got {tuple(x.shape)}")
        if cond is not None and not isinstance(cond, Tensor) and len(cond) != self.layers:
            raise ValueError(f"cond must hold one tensor per block ({self.layers}): {len(cond)}")
        if key_padding_mask is not None:
            if key_padding_mask.shape != x.shape[:2] or key_padding_mask.dtype != torch.bool:
                raise ValueError("key_padding_mask must be a (B, S) bool tensor, True = pad")

        def block(layer: nn.Module, h: Tensor, i: int) -> Tensor:
            c = self._cond(cond, i)
            if c is not None:
                h = h + c  # condition added at the input of every block
            return layer(h, src_key_padding_mask=key_padding_mask)

        skips: list[Tensor] = []
        i = 0
        for layer in self.input_blocks:
            x = block(layer, x, i)  # (B, S, d)
            skips.append(x)
            i += 1
        x = block(self.middle_block, x, i)
        i += 1
        for layer, linear in zip(self.output_blocks, self.skip_linears):
            x = linear(torch.cat([x, skips.pop()], dim=-1))  # (B, S, 2d) -> (B, S, d)
            x = block(layer, x, i)
            i += 1
        return self.norm(x)  # (B, S, d)
