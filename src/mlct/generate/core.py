"""The core of generation: text -> latents -> features -> joints, one batch per call.

    core = MotionCore(TorchNetworks(meta, tensors))
    feats = core.features(core.encode_text(["a person walks"]), None, [0], None, [120])

It holds the model's networks behind the backend interface (backends/base.py: torch, onnx,
cuda graphs) and knows nothing of prompts: splitting them, their lengths, the critic's choice
and the rest are the composer's (compose/generator.py), which calls `features` once per batch.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any, Callable, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.generate.backends.base import Networks
from mlct.generate.seeds import Sampling, candidate_seeds, is_int

TEXT_MEMO_SIZE = 2048  # texts whose embeddings a generator keeps (LRU): <= 64 MB with tokens

# (latents (B * N, n, d) over latent_scale, N) -> the index (B,) of each item's best candidate
Chooser = Callable[[Any, int], Any]


class MotionCore:
    """A model's networks (one backend), its sampler and skeleton, and the text memo.

    read_as: how a text is given to the text encoder (the composer's actions.plain_subject: a
    subject the training captions never used is read as "a person"); default: as it is."""

    def __init__(self, networks: Networks, read_as: Callable[[str], str] = str) -> None:
        self.networks, self.read_as = networks, read_as
        self.meta, self.config = networks.meta, networks.config
        self.device, self.skeleton, self.sampler = (networks.device, networks.skeleton,
                                                    networks.sampler)
        self._text_memo: OrderedDict[str, Any] = OrderedDict()

    @property
    def max_frames(self) -> int:
        return self.config.data.max_motion_length

    @property
    def default_nfe(self) -> int:
        return self.sampler.default_steps

    def frames_for(self, seconds: float) -> int:
        return int(round(seconds * self.skeleton.fps))

    def check_nfe(self, nfe: int | None) -> int:
        """The step count to sample with (the default for None); MlctError when out of range."""
        if nfe is not None and not is_int(nfe):
            raise MlctError(f"nfe must be a whole number of steps, got {nfe!r}")
        return self.sampler.check_steps(nfe)

    def encode_text(self, texts: Sequence[str]) -> Any:
        """(B, c) frozen text embeddings. The last TEXT_MEMO_SIZE distinct texts are kept, so a
        repeated prompt skips the encoder; the memo's memory is bounded (a server sees many).
        Each text is read as `read_as` gives it. A numpy array on the numpy backends
        (networks.numpy: onnx), else a tensor."""
        texts = [self.read_as(t) for t in texts]
        found = {t: self._text_memo[t] for t in texts if t in self._text_memo}
        missing = sorted(set(texts) - set(found))
        if missing:
            found.update(zip(missing, self._encoded(missing)))
        for text in texts:  # most recently used last; the oldest go first
            self._text_memo[text] = found[text]
            self._text_memo.move_to_end(text)
        while len(self._text_memo) > TEXT_MEMO_SIZE:
            self._text_memo.popitem(last=False)
        return self._stacked([found[t] for t in texts], to_device=True)

    def _encoded(self, texts: list[str]) -> Any:
        """The text encoder's rows of texts: arrays on the numpy backends, else tensors."""
        encoder = self.networks.text_encoder()
        if self.networks.numpy:
            return list(encoder.encode_numpy(texts))
        return [row.float() for row in encoder.encode(texts)]

    def _stacked(self, rows: list[Any], to_device: bool = False) -> Any:
        if self.networks.numpy:
            return np.stack(rows)
        import torch

        out = torch.stack(rows)
        return out.to(self.device) if to_device else out

    def judged_vectors(self, texts: Sequence[str]) -> Any:
        """encode_text's vectors (B, c) for judging: from its memo where there (the vectors the
        motions were made from), else encoded now and not kept."""
        keys = [self.read_as(t) for t in texts]
        found = {k: self._text_memo[k] for k in keys if k in self._text_memo}
        missing = sorted(set(keys) - set(found))
        if missing:
            found.update(zip(missing, self._encoded(missing)))
        return self._stacked([found[k] for k in keys])

    def _uncond(self) -> Any:
        """The null text (1, c) of classifier-free guidance, or None without it."""
        return self.encode_text([""]) if self.sampler.cfg else None

    def sample_latents(self, cond: Any, nfe: int | None = None,
                       seed: int | Sequence[int] | None = None, guidance: float | None = None
                       ) -> Any:
        """(B, n, d) latents for text embeddings cond (B, c). NFE = denoiser evaluations.

        seed: an int seeds one generator for the whole batch; a sequence seeds each item on its
        own (item i's latent is then independent of the rest of the batch); None is random."""
        steps = self.check_nfe(nfe)
        return self.networks.latents(cond, steps, seed, guidance, self._uncond())

    def decode(self, z: Any, lengths: Sequence[int]) -> list[np.ndarray]:
        """Stage 2's latents (sample_latents) -> denormalized features, one (T_i, D) array per
        item."""
        return self.networks.decode(z, lengths)

    def sample_features(self, cond: Any, nfe: int | None, seed: int | Sequence[int] | None,
                        guidance: float | None, lengths: Sequence[int]) -> list[np.ndarray]:
        """decode(sample_latents(...)): the features of motions of `lengths` frames; a backend
        may do both in one call (the onnx backend's sampler graph)."""
        steps = self.check_nfe(nfe)
        return self.networks.features(cond, steps, seed, guidance, self._uncond(), lengths)

    def features(self, cond: Any, seeds: Sequence[int], lengths: Sequence[int], how: Sampling,
                 choose: Chooser | None = None) -> list[np.ndarray]:
        """One batch: each item's features, from how.candidates latents where `choose` picks
        the best (the composer's critic), else the plain sample of its seed. The candidates of
        a seed are seeds.candidate_seeds; the first is the plain sample."""
        candidates, uncond = how.candidates, self._uncond()
        if candidates == 1 or choose is None:
            return self.networks.features(cond, how.steps, list(seeds), how.guidance, uncond,
                                          lengths)
        scale = self.config.schedule.latent_scale
        if isinstance(cond, np.ndarray):
            rows = np.repeat(cond, candidates, axis=0)
        else:
            rows = cond.repeat_interleave(candidates, dim=0)
        z = self.networks.latents(rows, how.steps, candidate_seeds(seeds, candidates),
                                  how.guidance, uncond)
        if isinstance(z, np.ndarray):  # the onnx backend's batches below TORCH_MIN_BATCH
            best = np.asarray(choose(z / np.float32(scale), candidates))
            z = z.reshape(len(seeds), candidates, *z.shape[1:])[np.arange(len(seeds)), best]
            return self.decode(z, lengths)
        import torch

        best = torch.as_tensor(choose(z.float().cpu() / scale, candidates))
        z = z.view(len(seeds), candidates, *z.shape[1:])
        z = z[torch.arange(len(seeds), device=z.device), best.to(z.device)]
        return self.decode(z, lengths)

    def joints(self, features: np.ndarray) -> np.ndarray:
        """(T, J, 3) joints of denormalized features (T, D) (numpy: motion/joints.py)."""
        from mlct.motion.joints import features_to_joints

        return features_to_joints(features)
