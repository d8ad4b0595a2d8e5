"""The one place a user's device string becomes a torch.device."""

from __future__ import annotations

import torch

from mlct.errors import MlctError

DEVICE_TYPES = ("cpu", "cuda")  # what mlct's models are built and tested on


def resolve_device(device: str | torch.device | None) -> torch.device:
    """`device`, checked (one line when unknown or unusable); None: cuda when available, else cpu."""
    if device is None:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError) as error:
        raise MlctError(f"unknown device {device!r} ({error})") from None
    # torch names more device types than this build can use ("mps", "meta", "xla", ...): moving
    # a model there fails deep inside torch, or ("meta") computes nothing at all.
    if dev.type not in DEVICE_TYPES:
        raise MlctError(f"device {device!r}: mlct runs on {' or '.join(DEVICE_TYPES)}")
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise MlctError(f"device {device!r}: CUDA is not available")
    if dev.type == "cuda" and dev.index is not None and dev.index >= torch.cuda.device_count():
        raise MlctError(f"device {device!r}: this machine has {torch.cuda.device_count()} CUDA "
                        f"device(s)")
    return dev
