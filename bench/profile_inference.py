"""Where the time of one motion goes: the bundled model at batch 1, 196 frames, per part.

    python bench/profile_inference.py [--backends torch,onnx-per-step,onnx] [--threads 1]
                                      [--runs 40]
                                      [--nfe 5] [--cpu-time]

Per backend (mlct.load's), medians over --runs of each part of generate() timed on its own:
the tokenizer; the text network; the text encoder as generate() calls it (memo bypassed);
the noise and the sampler's host-side arithmetic; the NFE network calls; the decoder;
denormalization; joint recovery (features -> 22 joints); then whole generate() calls, warm
(the caption seen before) and cold (the memo emptied). On the onnx backend also the one-call
sampler graph (sampling + decoding). Last, warm generate() calls of the backends taking turns,
run by run (the figures to compare on a busy machine). --cpu-time times with the thread's CPU clock instead of the
wall clock: with --threads 1 it leaves out the time other processes hold the core, so figures
on a busy machine stay comparable (ONNX Runtime's and PyTorch's work then runs on this thread).
"""

from __future__ import annotations

import argparse
import time
from typing import Any, Callable

import numpy as np
import torch

import mlct
from mlct.generate.onnx_backend import OnnxMotionGenerator
from mlct.motion.features import recover_from_ric

TEXTS = ["a person walks forward", "someone jumps up and down twice",
         "a man waves his right hand", "the person turns around and sits down"]
FRAMES = 196


def profile(gen: Any, nfe: int, runs: int, clock: Callable[[], float]) -> dict[str, float]:
    """Median ms of each part (module docstring)."""
    parts: dict[str, list[float]] = {}
    calls: list[float] = []
    onnx = isinstance(gen, OnnxMotionGenerator)
    net = gen.denoiser
    if onnx:  # time the denoiser graph's calls inside the step loop (either path)
        session = net.session

        class Timed:
            def run(self, *args: Any) -> Any:
                start = clock()
                out = session.run(*args)
                calls.append(clock() - start)
                return out

        net.session = Timed()
    else:
        forward = net.forward

        def timed(*args: Any, **kwargs: Any) -> Any:
            start = clock()
            out = forward(*args, **kwargs)
            calls.append(clock() - start)
            return out

        net.forward = timed
    encoder = gen.text_encoder
    gen.encode_text(TEXTS)

    def add(name: str, seconds: float) -> None:
        parts.setdefault(name, []).append(seconds * 1000.0)

    for i in range(runs + 5):
        text = TEXTS[i % len(TEXTS)]
        t0 = clock()
        ids = encoder.tokenizer.encode_batch([text])
        padded = encoder._pad([ids[0].ids])
        t1 = clock()
        encoder._run(*padded)
        t2 = clock()
        cond = encoder.encode([text]).float()
        t3 = clock()
        calls.clear()
        z = gen.sample_latents(cond, nfe, seed=i)
        t4 = clock()
        network = sum(calls)
        with torch.inference_mode():
            latent = z / gen.config.schedule.latent_scale
            feats = gen.ae.decode(latent, torch.tensor([FRAMES]), FRAMES)
            t5 = clock()
            feats = feats.float() * gen.std + gen.mean
            t6 = clock()
            recover_from_ric(feats[0])
            t7 = clock()
        if onnx:
            gen.sample_features(cond, nfe, [i], None, [FRAMES])
        t7b = clock()
        gen.encode_text([text])  # into the memo: the next call is warm
        t8 = clock()
        gen.generate(text, lengths=FRAMES, nfe=nfe, seed=i)
        t9 = clock()
        gen._text_memo.clear()
        gen.generate(text, lengths=FRAMES, nfe=nfe, seed=i)
        t10 = clock()
        if i < 5:  # warm-up
            continue
        add("tokenizer", t1 - t0)
        add("text network", t2 - t1)
        add("text encoder (as called)", t3 - t2)
        add(f"{nfe} denoiser calls", network)
        add("sampler host arithmetic", t4 - t3 - network)
        add("decoder", t5 - t4)
        add("denormalization", t6 - t5)
        add("joint recovery", t7 - t6)
        if onnx:
            add("sample_features (sampling + decoding)", t7b - t7)
        add("generate(), warm", t9 - t8)
        add("generate(), cold", t10 - t9)
    return {name: float(np.median(v)) for name, v in parts.items()}


def load(backend: str) -> Any:
    """torch; onnx (graphs from the model directory or auto's cache); onnx-per-step: the onnx
    backend as it was before issue 17's second part, the torch sampler's per-step code around
    the denoiser graph and no sampler graph."""
    if backend == "torch":
        return mlct.load(backend="torch")
    gen = mlct.load(backend="auto")
    if gen.backend != "onnx":
        raise SystemExit(f"the onnx backend cannot run here: {gen.backend_note}")
    if backend == "onnx-per-step":
        from mlct.generate.pipeline import MotionGenerator

        gen.fused = False
        gen.sample_latents = MotionGenerator.sample_latents.__get__(gen)
    elif backend != "onnx":
        raise SystemExit(f"unknown backend {backend!r}: torch, onnx or onnx-per-step")
    return gen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backends", default="torch,onnx-per-step,onnx")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--nfe", type=int, default=5)
    parser.add_argument("--cpu-time", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    clock = time.thread_time if args.cpu_time else time.perf_counter
    results = {}
    gens = {backend: load(backend) for backend in args.backends.split(",")}
    for gen in gens.values():
        # a 9.8-s walk asked of generate() would be remade as chained takes
        # (generate/keep_going.py); this profile times one sampling of the networks
        gen.keep_going = False
    for backend, gen in gens.items():
        results[backend] = profile(gen, args.nfe, args.runs, clock)
    # The backends one after the other above see different moments of a busy machine; here
    # they take turns, run by run, so the load hits them alike (the figures to compare).
    turns: dict[str, list[float]] = {backend: [] for backend in gens}
    for i in range(args.runs + 3):
        for backend, gen in gens.items():
            gen.encode_text([TEXTS[i % len(TEXTS)]])
            start = clock()
            gen.generate(TEXTS[i % len(TEXTS)], lengths=FRAMES, nfe=args.nfe, seed=i)
            if i >= 3:
                turns[backend].append((clock() - start) * 1000.0)
    for backend, times in turns.items():
        results[backend]["generate(), warm, taking turns"] = float(np.median(times))
    names = list(dict.fromkeys(n for r in results.values() for n in r))
    kind = "thread CPU time" if args.cpu_time else "wall time"
    print(f"bundled model, batch 1, {FRAMES} frames, {args.nfe} NFE, {args.threads} thread(s), "
          f"medians of {args.runs} runs in ms ({kind})")
    print(f"{'part':<38}" + "".join(f"{b:>15}" for b in results))
    for name in names:
        print(f"{name:<38}" + "".join(f"{r[name]:>15.2f}" if name in r else f"{'':>15}"
                                      for r in results.values()))


if __name__ == "__main__":
    main()
