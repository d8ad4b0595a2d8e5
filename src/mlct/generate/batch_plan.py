"""One sampler batch for a whole list of prompts, whatever each prompt becomes.

generate() turns a prompt into one or more samples of the model: a plain prompt is one; a
sequence ("walks forward, then waves") one per action (long_motion.generate_long); an arm
action done during another ("walks while waving") a body and its arms (pipeline._concurrent);
a gait asked for past its natural length several takes (keep_going). Those paths call
generate() again, one prompt at a time, so a list of 64 sequences sampled 64 small batches
(29 motions/s against 177 for 64 plain prompts, torch, 2 threads).

Each sample depends only on its (text, length, seed, nfe, guidance, candidates): every item
draws its noise from its own seed (pipeline.generators_for), so it does not matter which batch
it is made in. So the outermost generate() of a list first lists the samples its prompts will
ask for (`planned_samples`, the same decisions as MotionGenerator._made in the same order), makes
them all in a few large batches, and keeps them in a `SampleMemo` that best_features reads
before it samples. The per-prompt paths then run as before and find their samples made. A
sample the plan did not foresee (a keep-going take; `pipeline._keep_going` asks for those in
one batch of its own) is made where it is asked for, as before: a plan can only save time,
never change a motion beyond float rounding.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor

from mlct.generate.compose import split_actions as split_actions_of
from mlct.generate.compose import split_concurrent
from mlct.generate.prompts import clean_prompt

# Latents per sampler call when filling the memo (a sample is `candidates` latents). On a CPU
# the time per motion is least near 64 and grows past a few hundred, where a batch's
# activations leave the cache (docs/performance.md: 335 motions/s at
# 64, 284 at 512, 195 at 4,096). A GPU wants thousands (75,000 motions/s at 4,096 on an H200).
PREFETCH_LATENTS = {"cpu": 64, "cuda": 4096}


@dataclass(frozen=True)
class Sample:
    """One sample the model will be asked for: its text (as the model reads it), its length in
    frames and its seed."""

    text: str
    frames: int
    seed: int


def planned_samples(pipe: Any, texts: Sequence[str], frames: Sequence[int],
                    seeds: Sequence[int], split_actions: bool) -> list[Sample]:
    """The samples generate(texts, lengths=frames, seed=seeds, split_actions=...) will ask the
    model for, as far as the prompts alone decide them (keep-going takes depend on the first
    sample and are not listed). Mirrors MotionGenerator._made and generate_long; `pipe` is
    the MotionGenerator (not imported: it imports this module)."""
    from mlct.generate.long_motion import blend_frames

    blend = blend_frames(pipe.skeleton.fps)
    min_part = pipe.min_part_frames()
    out: list[Sample] = []
    for text, n, seed in zip(texts, frames, seeds):
        if split_actions and (pair := split_concurrent(text)) is not None:
            for part in pair:  # _concurrent: generate(body) and generate(arms), the same seed
                out += planned_samples(pipe, [clean_prompt(part)], [n], [seed], True)
            continue
        parts = split_actions_of(text) if split_actions else [text]
        if len(parts) == 1 or n // len(parts) < min_part:
            out.append(Sample(text, min(n, pipe.max_frames), seed))
            continue
        # _chained -> generate_long: each part but the last also covers the next one's blend,
        # item k seeded seed + k, lengths through the same seconds round trip
        seconds = [k / pipe.skeleton.fps for k in pipe.part_frames(parts, n)]
        lengths = pipe._lengths(len(parts), None, seconds, pipe.longest_gait())
        lengths = [k + blend for k in lengths[:-1]] + [lengths[-1]]
        out += [Sample(clean_prompt(p), min(k, pipe.max_frames), seed + j)
                for j, (p, k) in enumerate(zip(parts, lengths))]
    return out


class SampleMemo:
    """Samples made ahead of their prompt's path: key -> denormalized features (T, D)."""

    def __init__(self, steps: int, guidance: float | None, candidates: int) -> None:
        self.steps, self.guidance, self.candidates = steps, guidance, candidates
        self._made: dict[tuple[bytes, int, int], np.ndarray] = {}

    def _key(self, row: Tensor, frames: int, seed: int) -> tuple[bytes, int, int]:
        return row.detach().float().cpu().numpy().tobytes(), int(frames), int(seed)

    def serves(self, steps: int, guidance: float | None, candidates: int) -> bool:
        """Whether a best_features call with these settings may read the memo."""
        return (steps, guidance, candidates) == (self.steps, self.guidance, self.candidates)

    def get(self, row: Tensor, frames: int, seed: int) -> np.ndarray | None:
        return self._made.get(self._key(row, frames, seed))

    def put(self, row: Tensor, frames: int, seed: int, features: np.ndarray) -> None:
        self._made[self._key(row, frames, seed)] = features


def fill(pipe: Any, memo: SampleMemo, samples: Sequence[Sample]) -> None:
    """Make every sample not yet in the memo, PREFETCH_LATENTS latents a call, and keep them."""
    unique = list(dict.fromkeys(samples))
    if not unique:
        return
    texts = list(dict.fromkeys(s.text for s in unique))
    rows = dict(zip(texts, pipe.encode_text(texts)))
    todo = [s for s in unique if memo.get(rows[s.text], s.frames, s.seed) is None]
    latents = PREFETCH_LATENTS.get(torch.device(pipe.device).type, PREFETCH_LATENTS["cpu"])
    per_call = max(1, latents // memo.candidates)
    for start in range(0, len(todo), per_call):
        chunk = todo[start:start + per_call]
        cond = torch.stack([rows[s.text] for s in chunk])
        made = pipe.sample_best(cond, memo.steps, [s.seed for s in chunk], memo.guidance,
                                [s.frames for s in chunk], memo.candidates)
        for s, feats in zip(chunk, made):
            memo.put(rows[s.text], s.frames, s.seed, feats)
