"""One sampler batch for a whole list of prompts, whatever each prompt becomes.

generate() turns a prompt into one or more samples of the model: a plain prompt is one; a
sequence ("walks forward, then waves") one per action (long_motion.generate_long); an arm
action done during another ("walks while waving") a body and its arms (pipeline._concurrent);
a gait asked for past its natural length several takes (keep_going). Those paths call
generate() again, one prompt at a time, so a list of 64 sequences sampled 64 small batches
(29 motions/s against 177 for 64 plain prompts, torch, 2 threads).

Each sample depends only on its (text, length, seed) and the call's Sampling: every item
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

import contextlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Iterator, Sequence

import numpy as np

from mlct.generate.compose.actions import split_actions as split_actions_of
from mlct.generate.compose.actions import split_concurrent
from mlct.generate.compose.lengths import MIN_PART_SECONDS, frame_lengths, longest_gait
from mlct.generate.compose.prompts import clean_prompt
from mlct.generate.seeds import Sampling

if TYPE_CHECKING:
    from torch import Tensor

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
    from mlct.generate.compose.long_motion import blend_frames
    from mlct.generate.compose.timing import part_frames

    blend = blend_frames(pipe.skeleton.fps)
    min_part = pipe.frames_for(MIN_PART_SECONDS)
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
        seconds = [k / pipe.skeleton.fps for k in part_frames(pipe, parts, n)]
        lengths = frame_lengths(pipe, len(parts), None, seconds, longest_gait(pipe))
        lengths = [k + blend for k in lengths[:-1]] + [lengths[-1]]
        out += [Sample(clean_prompt(p), min(k, pipe.max_frames), seed + j)
                for j, (p, k) in enumerate(zip(parts, lengths))]
    return out


class SampleMemo:
    """Samples made ahead of their prompt's path: key -> denormalized features (T, D)."""

    def __init__(self, how: Sampling) -> None:
        self.how = how
        self._made: dict[tuple[bytes, int, int], np.ndarray] = {}

    def _key(self, row: Tensor, frames: int, seed: int) -> tuple[bytes, int, int]:
        array = row if isinstance(row, np.ndarray) else row.detach().float().cpu().numpy()
        return np.asarray(array, np.float32).tobytes(), int(frames), int(seed)

    def serves(self, how: Sampling) -> bool:
        """Whether a best_features call with these settings may read the memo."""
        return how == self.how

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
    kind = str(pipe.device).split(":")[0]  # "cpu", "cuda"
    latents = PREFETCH_LATENTS.get(kind, PREFETCH_LATENTS["cpu"])
    per_call = max(1, latents // memo.how.candidates)
    for start in range(0, len(todo), per_call):
        chunk = todo[start:start + per_call]
        cond = _stack([rows[s.text] for s in chunk])
        made = pipe.sample_best(cond, [s.seed for s in chunk], [s.frames for s in chunk],
                                memo.how)
        for s, feats in zip(chunk, made):
            memo.put(rows[s.text], s.frames, s.seed, feats)


@contextlib.contextmanager
def made_ahead(gen: Any, texts: Sequence[str], frames: Sequence[int], seeds: Sequence[int],
               split_actions: bool, how: Sampling) -> Iterator[None]:
    """The outermost generate() makes every sample its prompts' paths will ask for in a
    few large batches first, where some prompt is more than one sample; the paths then read
    them (best_features)."""
    # One prompt's path already makes its own samples in one call (a sequence's parts,
    # a gait's takes), so only a list is planned: a batch of 1 pays nothing for it.
    if len(texts) < 2 or getattr(gen.nesting, "memo", None) is not None:
        yield  # one prompt, or an inner call (the outer made them)
        return
    planned = planned_samples(gen, texts, frames, seeds, split_actions)
    if [s.text for s in planned] == list(texts):  # one sample each: one batch already
        yield
        return
    with samples_ahead(gen, planned, how):
        yield


@contextlib.contextmanager
def samples_ahead(gen: Any, samples: Sequence[Sample], how: Sampling) -> Iterator[None]:
    """Within it, best_features reads these Samples, made now in a few large batches (added
    to the memo of an outer call with the same settings, else a new one)."""
    outer = getattr(gen.nesting, "memo", None)
    if outer is not None and outer.serves(how):
        fill(gen, outer, samples)
        yield
        return
    gen.nesting.memo = SampleMemo(how)
    try:
        fill(gen, gen.nesting.memo, samples)
        yield
    finally:
        gen.nesting.memo = outer


def best_features(gen: Any, cond: Tensor, seeds: Sequence[int], lengths: Sequence[int],
                  how: Sampling) -> list[np.ndarray]:
    """sample_best's features, taken from the samples the outermost generate() made ahead
    for its whole list of prompts where it made them."""
    memo = getattr(gen.nesting, "memo", None)
    if memo is None or not memo.serves(how):
        return gen.sample_best(cond, seeds, lengths, how)
    found = [memo.get(row, n, s) for row, n, s in zip(cond, lengths, seeds)]
    missing = [i for i, f in enumerate(found) if f is None]
    if missing:
        made = gen.sample_best(cond[missing], [seeds[i] for i in missing],
                               [lengths[i] for i in missing], how)
        for i, feats in zip(missing, made):
            found[i] = feats
    return found  # type: ignore[return-value]


def _stack(rows: list[Any]) -> Any:
    """Rows of text vectors as one batch: numpy arrays (the onnx backend) or tensors."""
    if isinstance(rows[0], np.ndarray):
        return np.stack(rows)
    import torch

    return torch.stack(rows)

