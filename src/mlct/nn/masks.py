"""Padding masks shared by the autoencoder, the denoiser and the losses."""

from __future__ import annotations

import torch
from torch import Tensor

from mlct.cuda_graphs import capturing


def lengths_to_mask(lengths: Tensor, max_len: int | None = None) -> Tensor:
    """(B,) lengths -> (B, T) bool mask, True = valid frame; T = max_len or max(lengths)."""
    if lengths.ndim != 1:
        raise ValueError(f"lengths must be 1-D (B,), got shape {tuple(lengths.shape)}")
    if max_len is None or not capturing():  # a CUDA graph cannot read them: checked before
        if lengths.numel() and int(lengths.min()) < 0:
            raise ValueError("lengths must be non-negative")
        longest = int(lengths.max()) if lengths.numel() else 0
        if max_len is None:
            max_len = longest
        elif longest > max_len:
            raise ValueError(f"a length {longest} exceeds max_len {max_len}")
    steps = torch.arange(max_len, device=lengths.device)  # (T,)
    return steps[None, :] < lengths[:, None]  # (B, T)
