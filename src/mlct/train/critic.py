"""`mlct train critic`: the text-motion critic of best-of-N sampling (nn/critic.py), trained on a
model's own latents and text vectors, written beside its weights (generate/compose/critic.py).

The motions of one split are encoded once by the model's autoencoder encoder (the bundle ships
it) and their captions once by the model's text encoder (through the disk cache). The loss is
CLIP's symmetric InfoNCE over a batch of (caption, latent) pairs, with two changes for this use:
- motions with the same label (labels.jsonl; the motion's name when there is none) are not
  counted as negatives of each other: the benchmark has many "walks forward" motions;
- a caption that names a side also competes with its mirror ("left" and "right" swapped,
  text/sides.py) as a negative for its own motion, and one that states a count or an angle
  with its recount ("four times" -> "five times", "45 degrees" -> "135 degrees"): the critic
  must tell sides and counts apart, what stage 2 gets wrong most often (docs/training.md).
The latents get Gaussian noise (LATENT_NOISE of their spread) so that the critic also rates the
slightly off-manifold latents a sampler returns.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from mlct.config import config_from_dict
from mlct.data.labels import LABELS_FILE, read_labels
from mlct.data.layout import DatasetLayout
from mlct.errors import MlctError
from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
from mlct.generate.compose.critic import DEFAULT_CANDIDATES, DEFAULT_MARGIN, save_critic
from mlct.nn.build import build_autoencoder
from mlct.nn.critic import LatentCritic
from mlct.text.sides import mirror_sides

LATENT_NOISE = 0.15
FOIL_BATCH = 64  # sampled motions per step whose candidates are ranked (critic_samples.py)
MASKED = -1e4  # a logit that softmax ignores

_NUMBERS = ("one", "two", "three", "four", "five")
_ANGLES = {"45": "135", "135": "45", "90": "180", "180": "90",
           "forty five": "a hundred and thirty five", "a hundred and thirty five": "forty five",
           "ninety": "a hundred and eighty", "a hundred and eighty": "ninety"}
# one pass, angles first, so that "forty five degrees" is an angle and never a count of five
_QUANTITY = re.compile(
    r"\b(?P<angle>" + "|".join(sorted(_ANGLES, key=len, reverse=True)) + r")(?= degrees)"
    r"|\b(?P<count>once|twice|one|two|three|four|five|[1-5])\b(?P<times> times?\b)?")


def recount(text: str) -> str:
    """The caption with every count one more (five wraps to two) and every angle swapped for
    another (45 <-> 135, 90 <-> 180); the caption itself when it states neither."""
    def swap(match: re.Match[str]) -> str:
        if match.group("angle"):
            return _ANGLES[match.group("angle")]
        word, times = match.group("count"), match.group("times") or ""
        n = {"once": 1, "twice": 2}.get(word) or (int(word) if word.isdigit()
                                                  else _NUMBERS.index(word) + 1)
        m = n + 1 if n < 5 else 2
        if word.isdigit():
            return f"{m}{' times' if times else ''}"
        if word in ("once", "twice") or times:
            return {2: "twice"}.get(m, f"{_NUMBERS[m - 1]} times")
        return _NUMBERS[m - 1]
    return _QUANTITY.sub(swap, text)


class CriticData:
    """One split's latents (M, n, d), lengths (M,), captions with their owner motion, text
    vectors (C, c) and their mirrors', and a group id per motion (same label, same group)."""

    def __init__(self, layout: DatasetLayout, names: list[str], labels: dict[str, Any],
                 encoder: Any, normalize: Any, max_frames: int) -> None:
        self.names = names
        feats = [layout.load_features(n)[:max_frames] for n in names]
        self.lengths = torch.tensor([len(f) for f in feats])
        self.latents = torch.cat([normalize(feats[i:i + 64]) for i in range(0, len(feats), 64)])
        captions, owner = [], []
        for i, name in enumerate(names):
            for record in layout.read_texts(name):
                captions.append(record.caption)
                owner.append(i)
        if not captions:
            raise MlctError(f"{layout.root}: the motions have no captions")
        self.captions, self.owner = captions, torch.tensor(owner)
        self.text = encoder.encode(captions).float()
        self.sided, self.mirror = self._foils(mirror_sides, encoder)
        self.counted, self.recount = self._foils(recount, encoder)
        keys = [labels.get(n, {}).get("label", n) for n in names]
        index = {k: g for g, k in enumerate(dict.fromkeys(keys))}
        self.group = torch.tensor([index[k] for k in keys])


    def _foils(self, change: Any, encoder: Any) -> tuple[Tensor, Tensor]:
        """(C,) which captions `change` alters, (C, c) the altered captions' vectors (a
        caption's own where it is not altered)."""
        changed = [change(c) for c in self.captions]
        mask = torch.tensor([a != c for c, a in zip(self.captions, changed)])
        vectors = self.text.clone()
        rows = [i for i, m in enumerate(mask.tolist()) if m]
        if rows:
            vectors[rows] = encoder.encode([changed[i] for i in rows]).float()
        return mask, vectors


def _loss(critic: LatentCritic, data: CriticData, rows: Tensor, noise: float) -> Tensor:
    own = data.owner[rows]
    z = data.latents[own]
    z = z + noise * torch.randn_like(z)
    motion = critic.motion(z, data.lengths[own])
    text, mirror = critic.text(data.text[rows]), critic.text(data.mirror[rows])
    scale = critic.logit_scale.exp().clamp(max=100.0)
    logits = scale * motion @ text.T  # (B, B): motion i against caption j
    group = data.group[own]
    same = (group[:, None] == group[None, :]) & ~torch.eye(len(rows), dtype=torch.bool)
    logits = logits.masked_fill(same, MASKED)
    mirrored = (scale * (motion * mirror).sum(-1, keepdim=True)).masked_fill(
        ~data.sided[rows][:, None], MASKED)
    recounted = (scale * (motion * critic.text(data.recount[rows])).sum(-1, keepdim=True)
                 ).masked_fill(~data.counted[rows][:, None], MASKED)
    target = torch.arange(len(rows))
    return (F.cross_entropy(torch.cat([logits, mirrored, recounted], dim=1), target)
            + F.cross_entropy(logits.T, target))


@torch.no_grad()
def measure(critic: LatentCritic, data: CriticData) -> dict[str, float]:
    """Caption -> motion retrieval over the split: how often the best-rated motion has the
    caption's label (top-1), and how often a side-naming caption rates its own motion above
    its mirror caption does."""
    critic.eval()
    motion = critic.motion(data.latents, data.lengths)
    text, mirror = critic.text(data.text), critic.text(data.mirror)
    top = (text @ motion.T).argmax(dim=1)
    label_top1 = (data.group[top] == data.group[data.owner]).float().mean()
    own = (text * motion[data.owner]).sum(-1)
    other = (mirror * motion[data.owner]).sum(-1)
    sides = ((own > other)[data.sided].float().mean() if data.sided.any()
             else torch.tensor(float("nan")))
    recounted = (critic.text(data.recount) * motion[data.owner]).sum(-1)
    counts = ((own > recounted)[data.counted].float().mean() if data.counted.any()
              else torch.tensor(float("nan")))
    critic.train()
    return {"label_top1": round(float(label_top1), 4), "side_vs_mirror": round(float(sides), 4),
            "count_vs_recount": round(float(counts), 4)}


def train_critic(data_dir: str | os.PathLike, model_dir: str | os.PathLike,
                 split: str = "train", steps: int = 3000, batch_size: int = 256, lr: float = 1e-3,
                 seed: int = 0, eval_split: str | None = "test",
                 candidates: int = DEFAULT_CANDIDATES, samples: int = 0,
                 judge: Any = None, log: Any = print,
                 margin: float = DEFAULT_MARGIN) -> dict[str, Any]:
    """Train the critic of the model in `model_dir` on `split` and write critic.safetensors
    there; returns what it measured (on `eval_split` when the data has it).

    samples: K > 0 also ranks the model's own K samples of each one-action training motion by
    the benchmark's read-outs, `judge` (mlct.eval.readouts.evaluate_label; train/
    critic_samples.py; needs labels.jsonl)."""
    if steps < 1 or batch_size < 2:
        raise MlctError(f"steps must be >= 1 and batch size >= 2, got {steps} and {batch_size}")
    from mlct.text import load_text_encoder
    from mlct.text.cache import CachedTextEncoder

    torch.manual_seed(seed)
    meta, tensors = read_bundle(model_dir)
    config = config_from_dict(meta["config"], "model config")
    ae = build_autoencoder(config, int(meta["feature_dim"]))
    ae.load_state_dict(bundle_autoencoder_state(tensors, model_dir))
    ae.eval()
    mean, std = tensors["norm.mean"].float(), tensors["norm.std"].float()
    max_frames = config.data.max_motion_length

    @torch.no_grad()
    def encode(feats: list[np.ndarray]) -> Tensor:
        lengths = torch.tensor([len(f) for f in feats])
        x = torch.zeros(len(feats), int(lengths.max()), mean.shape[0])
        for i, f in enumerate(feats):
            x[i, :len(f)] = (torch.from_numpy(f).float() - mean) / std
        return ae.encode(x, lengths).z

    layout = DatasetLayout.existing(data_dir)
    labels = read_labels(data_dir) if (Path(data_dir) / LABELS_FILE).is_file() else {}
    encoder = CachedTextEncoder(load_text_encoder(meta["text_encoder"]))
    started = time.perf_counter()
    train = CriticData(layout, layout.read_split(split), labels, encoder, encode, max_frames)
    held = None
    if eval_split and (Path(data_dir) / f"{eval_split}.txt").is_file():
        held = CriticData(layout, layout.read_split(eval_split), labels, encoder, encode,
                          max_frames)
    log(f"critic: {len(train.names)} motions, {len(train.captions)} captions of '{split}' "
        f"encoded in {time.perf_counter() - started:.0f} s")
    foils = held_foils = None
    if samples:
        from mlct.train.critic_samples import sample_foils

        if judge is None:
            raise MlctError("ranking the model's samples needs the read-outs' judge "
                            "(mlct.eval.readouts.evaluate_label)")
        foils = sample_foils(model_dir, layout, train.names, labels, samples, seed, max_frames,
                             judge, log)
        if held is not None:
            held_foils = sample_foils(model_dir, layout, held.names, labels, samples, seed + 1,
                                      max_frames, judge, log)
    shape = train.latents.shape
    critic = LatentCritic(shape[1] * shape[2], train.text.shape[1], max_frames)
    optimizer = torch.optim.AdamW(critic.parameters(), lr=lr, weight_decay=1e-4)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps, eta_min=lr * 0.01)
    noise = LATENT_NOISE * float(train.latents.std())
    generator = torch.Generator().manual_seed(seed)
    for step in range(1, steps + 1):
        rows = torch.randint(len(train.captions), (batch_size,), generator=generator)
        loss = _loss(critic, train, rows, noise)
        if foils is not None:
            from mlct.train.critic_samples import ranking_loss

            picked = torch.randint(len(foils.text), (min(FOIL_BATCH, len(foils.text)),),
                                   generator=generator)
            loss = loss + ranking_loss(critic, foils, picked)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        schedule.step()
        if step % 500 == 0 or step == steps:
            log(f"critic: step {step}/{steps}, loss {float(loss.detach()):.3f}")
    training = {"data": str(data_dir), "split": split, "motions": len(train.names),
                "captions": len(train.captions), "steps": steps, "batch_size": batch_size,
                "lr": lr, "seed": seed, "seconds": round(time.perf_counter() - started, 1),
                "train": measure(critic, train)}
    if held is not None:
        training[eval_split] = measure(critic, held)
    if foils is not None:
        from mlct.train.critic_samples import base_rate, ranking_accuracy

        training["samples"] = {**foils.info,
                               "train_best_passes": ranking_accuracy(critic, foils),
                               "train_random_passes": base_rate(foils)}
        if held_foils is not None:
            training["samples"][f"{eval_split}_best_passes"] = ranking_accuracy(critic,
                                                                                held_foils)
            training["samples"][f"{eval_split}_random_passes"] = base_rate(held_foils)
            training["samples"][f"{eval_split}_mixed"] = held_foils.info["mixed"]
    save_critic(model_dir, critic, training, meta["text_encoder"], candidates, margin)
    return training
