"""A text-motion critic in the latent space: how well a latent's motion matches a text (ours).

Two small MLPs map the autoencoder's latent (flattened n x d, plus the motion's length as a
fraction of the horizon) and the frozen text vector into one 256-d space; the score is their
cosine. Trained contrastively (train/critic.py) as CLIP and the text-motion evaluators are
(Guo et al. 2022; TMR, Petrovich et al. 2023), but on latents, not frames: scoring N sampled
latents costs two matrix products and no decoder, so a consistency model can sample N motions
for a prompt and keep the one the critic rates best (generate/compose/critic.py) for a fraction of a
millisecond more than the sampling.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn


class LatentCritic(nn.Module):
    """score(z, frames, text) = cos(motion(z, frames), text(text))."""

    def __init__(self, latent_size: int, text_dim: int, max_frames: int, hidden: int = 512,
                 width: int = 256) -> None:
        super().__init__()
        self.latent_size, self.text_dim, self.max_frames = latent_size, text_dim, max_frames
        self.hidden, self.width = hidden, width
        self.motion_net = nn.Sequential(nn.Linear(latent_size + 1, hidden), nn.GELU(),
                                        nn.Linear(hidden, hidden), nn.GELU(),
                                        nn.Linear(hidden, width))
        self.text_net = nn.Sequential(nn.Linear(text_dim, hidden), nn.GELU(),
                                      nn.Linear(hidden, width))
        # CLIP's learnable temperature, started at 1 / 0.07; used by the training loss only
        self.logit_scale = nn.Parameter(torch.tensor(2.6593))

    def motion(self, z: Tensor, frames: Tensor) -> Tensor:
        """(B, n, d) autoencoder latents, (B,) lengths in frames -> (B, width) unit vectors."""
        x = torch.cat([z.flatten(1), (frames.to(z) / self.max_frames)[:, None]], dim=-1)
        return F.normalize(self.motion_net(x), dim=-1)

    def text(self, text_emb: Tensor) -> Tensor:
        """(B, c) frozen text vectors -> (B, width) unit vectors."""
        return F.normalize(self.text_net(text_emb), dim=-1)

    def score(self, z: Tensor, frames: Tensor, text_emb: Tensor) -> Tensor:
        """(B,) cosine of each latent's motion with its own text."""
        return (self.motion(z, frames) * self.text(text_emb)).sum(-1)
