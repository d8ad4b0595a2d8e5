"""AITS, the average inference time per sentence (MLD Sec. 4; MLCT Table 1).

Batch 1, 196 frames, after warm-up runs, loading excluded: the time of text encoding + sampling
+ decoding, each part timed on its own (CUDA synchronized at every boundary). The text is encoded
afresh in every run (the generator's memo of seen captions is bypassed), and each run takes the
next caption of the list. NFE counts denoiser evaluations; DDIM with classifier-free guidance
runs two network passes per step (one batch of cond + uncond).

Besides the means (the papers' AITS) it reports medians, which a busy machine disturbs less,
and the text part when the caption was seen before (`text_cached_ms`: the generator's memo), the
figure a server that repeats captions pays. bench/inference_speed.py builds on this.
"""

from __future__ import annotations

import time
from typing import Any, Sequence

import numpy as np
import torch

from mlct.errors import MlctError
from mlct.generate.compose.generator import MotionGenerator


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def time_inference(gen: MotionGenerator, texts: Sequence[str], *, nfe: int | None = None,
                   guidance: float | None = None, frames: int = 196, runs: int = 10,
                   warmup: int = 3) -> dict[str, Any]:
    """Milliseconds per sentence: total and its text / sampling / decoding parts, as means
    (`aits_ms`, `text_ms`, ...) and medians (`median`: the same keys plus `text_cached_ms`)."""
    if runs < 1 or warmup < 0 or not texts:
        raise MlctError(f"AITS needs runs >= 1, warmup >= 0 and a text (runs {runs}, "
                        f"warmup {warmup}, {len(texts)} texts)")
    steps = gen.check_nfe(nfe)
    device = gen.device
    parts = np.zeros((runs, 4))  # text, sampling, decoding, text from the memo
    gen.encode_text([texts[i % len(texts)] for i in range(warmup + runs)])  # fill the memo
    with torch.no_grad():
        for i in range(warmup + runs):
            text = texts[i % len(texts)]
            _sync(device)
            tc = time.perf_counter()
            gen.encode_text([text])  # a memo hit
            _sync(device)
            t0 = time.perf_counter()
            cond = gen.text_encoder.encode([text]).float().to(device)  # (1, c), not memoized
            _sync(device)
            t1 = time.perf_counter()
            z = gen.sample_latents(cond, steps, seed=i, guidance=guidance)
            _sync(device)
            t2 = time.perf_counter()
            gen.decode(z, [frames])  # features in real units, on the CPU
            _sync(device)
            t3 = time.perf_counter()
            if i >= warmup:
                parts[i - warmup] = (t1 - t0, t2 - t1, t3 - t2, t0 - tc)
    text_ms, sampling_ms, decoding_ms, _ = (parts.mean(axis=0) * 1000.0).tolist()
    medians = np.median(parts, axis=0) * 1000.0
    return {"aits_ms": text_ms + sampling_ms + decoding_ms, "text_ms": text_ms,
            "sampling_ms": sampling_ms, "decoding_ms": decoding_ms,
            "aits_ms_std": float(parts[:, :3].sum(axis=1).std() * 1000.0),
            "median": {"aits_ms": float(np.median(parts[:, :3].sum(axis=1)) * 1000.0),
                       "text_ms": float(medians[0]), "sampling_ms": float(medians[1]),
                       "decoding_ms": float(medians[2]), "text_cached_ms": float(medians[3])},
            "frames": frames, "batch": 1, "runs": runs, "warmup": warmup, "device": str(device)}
