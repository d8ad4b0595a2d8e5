"""A dataset's motions held on the training device, each batch's crops gathered there.

Why: fed by DataLoader workers, a batch of 64 motions padded to 196 frames is ~13 MB copied
from the host every step, and the GPU waits for the copy. Held on the device (the normalized
motions end to end, ~1 GB for 4,000 clips, ~5 GB for HumanML3D's 29,000), a batch is three
(B,) integer tensors drawn on the host exactly as before (Text2MotionDataset.choose: which
item, which first frame, how many frames) and one gather on the device, which a CUDA graph can
hold (train/captured_step.py).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from mlct.data.dataset import Text2MotionDataset


class ResidentMotions:
    """Every item's normalized motion, end to end in one (frames, D) tensor on `device`."""

    def __init__(self, dataset: Text2MotionDataset, device: torch.device) -> None:
        motions = [item.motion for item in dataset.items]
        lengths = np.array([len(m) for m in motions], dtype=np.int64)
        self.frames = dataset.max_motion_length  # the padded width of every batch
        # the first frame of each item; `frames` zero rows at the end so that a crop's gather
        # never indexes past the tensor (its frames beyond the length are masked anyway)
        self.offsets = torch.from_numpy(np.concatenate([[0], np.cumsum(lengths)[:-1]])).to(device)
        width = motions[0].shape[1]
        flat = np.concatenate([*motions, np.zeros((self.frames, width), dtype=np.float32)])
        self.flat = torch.from_numpy(flat.astype(np.float32, copy=False)).to(device)
        self._steps = torch.arange(self.frames, device=device)

    @property
    def nbytes(self) -> int:
        return self.flat.numel() * self.flat.element_size()

    def gather(self, index: Tensor, start: Tensor, length: Tensor) -> Tensor:
        """(B,) item index, first frame, length -> (B, frames, D): each crop from its first
        frame, zero past its length: what collate() stacks from Text2MotionDataset.sample."""
        rows = (self.offsets[index] + start)[:, None] + self._steps[None, :]  # (B, frames)
        valid = self._steps[None, :] < length[:, None]  # (B, frames)
        return self.flat[rows] * valid[..., None].to(self.flat.dtype)
