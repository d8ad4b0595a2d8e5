"""The model's own samples as foils of its critic (`mlct train critic --samples K`).

Trained only on the data's motions against other captions, the critic tells a wave from a walk
but not a good wave from a poor one: among the 8 candidates of "a person waves with the right
hand" its scores lay within 0.07 of each other, and for seed 0 it picked the one candidate of
the 8 whose wrist reversed 3 times, short of a wave's 4 (docs/training.md). Best-of-N needs the
second skill. So for each one-action motion of
the training split with a benchmark label (labels.jsonl), the model samples K latents from one
of its captions at the motion's length (the pipeline's own sampler), decodes them, and
the label's physical read-outs (mlct.eval.readouts, the checks the benchmark applies) say which
candidates do what the caption says. Where some pass and some fail, the critic learns to rate
each passing candidate above each failing one (a pairwise logistic term beside its InfoNCE).

Only the training split is sampled; bench/quality.py motion measures on the test split and on
hand-written prompts. One-action motions only: the pipeline makes a sequence one action at a
time and a concurrent arm action apart, so its critic only ever ranks single actions.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from mlct.data.layout import DatasetLayout
from mlct.errors import MlctError
from mlct.motion.features import features_to_joints

BATCH = 32  # motions per sampling batch (x K candidates)
# joints (T, J, 3) and a benchmark label -> [(check name, passed)]: mlct.eval.readouts'
# evaluate_label, handed in by the caller (eval sits beside train, not below it)
Judge = Callable[[np.ndarray, dict[str, Any]], list[tuple[str, bool]]]


@dataclass
class SampledFoils:
    """Per kept motion: its caption's text vector, its K sampled latents (autoencoder units),
    its length and which candidates passed its read-outs."""

    text: Tensor  # (R, c)
    latents: Tensor  # (R, K, n, d)
    frames: Tensor  # (R,)
    passed: Tensor  # (R, K) bool
    info: dict[str, Any]


@dataclass
class Judged:
    """One motion's K sampled candidates and the judge's verdict on each."""

    name: str
    text: Tensor  # (c,) its caption's text vector
    latents: Tensor  # (K, n, d) in the autoencoder's units
    features: list[np.ndarray]  # K x (T, D), real units
    joints: list[np.ndarray]  # K x (T, J, 3)
    passed: Tensor  # (K,) bool


def one_action_names(names: list[str], labels: dict[str, Any]) -> list[str]:
    """The names with a benchmark label of one action and no concurrent one, in order."""
    return [n for n in names if n in labels and len(labels[n]["actions"]) == 1
            and not labels[n].get("concurrent")]


def judged_candidates(pipe: Any, layout: DatasetLayout, names: list[str],
                      labels: dict[str, Any], samples: int, first_seed: int, max_frames: int,
                      judge: Judge) -> Iterator[Judged]:
    """For each motion of `names` (one-action, labelled), `samples` candidates from its first
    caption at its length, candidate k of the i-th motion with seed first_seed + i * samples + k,
    each judged on its joints against the motion's label."""
    for start in range(0, len(names), BATCH):
        chunk = names[start:start + BATCH]
        lengths = [min(len(layout.load_features(n)), max_frames) for n in chunk]
        cond = pipe.encode_text([layout.read_texts(n)[0].caption for n in chunk])
        seeds = [(first_seed + (start + i) * samples + k) % (2**31 - 1)
                 for i in range(len(chunk)) for k in range(samples)]
        with torch.inference_mode():
            z = pipe.sample_latents(cond.repeat_interleave(samples, dim=0), None, seeds, None)
            feats = pipe.decode(z, [n for n in lengths for _ in range(samples)])
        z = z.float().cpu().view(len(chunk), samples, *z.shape[1:])
        for i, name in enumerate(chunk):
            mine = feats[i * samples:(i + 1) * samples]
            joints = [features_to_joints(f) for f in mine]
            passed = torch.tensor([all(p for _, p in judge(j, labels[name])) for j in joints])
            yield Judged(name, cond[i].float().cpu(), z[i] / pipe.config.schedule.latent_scale,
                         mine, joints, passed)


def sample_foils(model_dir: str | os.PathLike, layout: DatasetLayout, names: list[str],
                 labels: dict[str, Any], samples: int, seed: int, max_frames: int,
                 judge: Judge, log: Any = print) -> SampledFoils:
    """K = `samples` candidates per one-action motion of `names` (module docstring), kept where
    the judge's read-outs disagree."""
    if samples < 2:
        raise MlctError(f"--samples must be >= 2 (candidates to rank), got {samples}")
    from mlct.generate.load import load

    pipe = load(model_dir, backend="torch")
    single = one_action_names(names, labels)
    if not single:
        raise MlctError(f"{layout.root}: no one-action motions with a benchmark label "
                        f"(labels.jsonl) to sample for the critic")
    started = time.perf_counter()
    text, latents, frames, passed = [], [], [], []
    total = 0
    for judged in judged_candidates(pipe, layout, single, labels, samples, seed * 1_000_003,
                                    max_frames, judge):
        total += 1
        if judged.passed.any() and not judged.passed.all():
            text.append(judged.text)
            latents.append(judged.latents)
            frames.append(len(judged.features[0]))
            passed.append(judged.passed)
        if total % (20 * BATCH) == 0 or total == len(single):
            log(f"critic: sampled {total} of {len(single)} motions x {samples}, "
                f"{len(text)} with mixed read-outs")
    info = {"samples": samples, "motions_sampled": total, "mixed": len(text),
            "seconds": round(time.perf_counter() - started, 1)}
    if not text:
        raise MlctError("no motion's samples disagree on the read-outs: nothing to rank")
    return SampledFoils(torch.stack(text), torch.stack(latents), torch.tensor(frames),
                        torch.stack(passed), info)


def ranking_loss(critic: Any, foils: SampledFoils, rows: Tensor) -> Tensor:
    """Pairwise logistic loss: each passing candidate of a row above each failing one."""
    z = foils.latents[rows]  # (B, K, n, d)
    b, k = z.shape[:2]
    scale = critic.logit_scale.exp().clamp(max=100.0)
    scores = scale * critic.score(z.flatten(0, 1), foils.frames[rows].repeat_interleave(k),
                                  foils.text[rows].repeat_interleave(k, dim=0)).view(b, k)
    ok = foils.passed[rows]
    pairs = ok[:, :, None] & ~ok[:, None, :]  # [b, p, f]: p passed, f failed
    gaps = scores[:, None, :] - scores[:, :, None]  # score(f) - score(p)
    return (F.softplus(gaps) * pairs).sum() / pairs.sum().clamp(min=1)


@torch.no_grad()
def ranking_accuracy(critic: Any, foils: SampledFoils) -> float:
    """Of the rows, how often the critic's best candidate is one that passed."""
    was_training = critic.training
    critic.eval()
    b, k = foils.passed.shape
    scores = critic.score(foils.latents.flatten(0, 1), foils.frames.repeat_interleave(k),
                          foils.text.repeat_interleave(k, dim=0)).view(b, k)
    critic.train(was_training)
    best = scores.argmax(dim=1)
    return round(float(foils.passed[torch.arange(b), best].float().mean()), 4)


def base_rate(foils: SampledFoils) -> float:
    """How often a candidate drawn at random passed, over the kept rows."""
    return round(float(np.mean(foils.passed.float().mean(dim=1).numpy())), 4)
