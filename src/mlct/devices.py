"""The one place a user's device string becomes a torch.device."""

from __future__ import annotations

import torch

from mlct.errors import MlctError


def resolve_device(device: str | torch.device | None) -> torch.device:
    """`device`, checked (one line when unknown or unusable); None: cuda when available, else cpu."""
    if device is None:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError) as error:
        raise MlctError(f"unknown device {device!r} ({error})") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise MlctError(f"device {device!r}: CUDA is not available")
    return dev
