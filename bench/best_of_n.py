"""What best-of-N sampling costs: a prompt's generate() time with 1, 4, 8 and 16 candidates.

    python bench/best_of_n.py [--model DIR] [--backends torch,auto] [--repeat 30] [--threads 2]

An onnx generator (auto picks one when onnxruntime is installed) samples a batch of
TORCH_MIN_BATCH latents or more with the torch networks; its row "... onnx only" is the same
generator with that turned off, timed in the same run.

Batch 1, 5 NFE, 196 frames, a warm text (the prompt's vector memoized, as a server or a batch
loop has it), interleaved run by run so that a busy machine slows every column alike; prints
the median and the ratio to one candidate. The critic's own scoring is timed apart.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

import mlct
from mlct.errors import MlctError


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--backends", default="torch,auto")
    parser.add_argument("--candidates", default="1,4,8,16")
    parser.add_argument("--repeat", type=int, default=30)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    counts = [int(c) for c in args.candidates.split(",")]
    gens = {}
    for backend in args.backends.split(","):
        try:
            gens[backend] = mlct.load(args.model, backend=backend)
        except MlctError as err:
            print(f"{backend}: skipped ({err})")
            continue
        if getattr(gens[backend], "torch_min_batch", None) is not None:
            only = mlct.load(args.model, backend=backend)
            only.torch_min_batch = None
            gens[f"{backend} onnx only"] = only
    text = "a person jumps twice"
    times: dict[tuple[str, int], list[float]] = {(b, n): [] for b in gens for n in counts}
    for gen in gens.values():
        gen.encode_text([text])
        for n in counts:  # warm-up: graphs built, caches filled
            gen.generate(text, lengths=196, seed=0, candidates=n)
            gen.generate(text, lengths=196, seed=0, candidates=n)
    for r in range(args.repeat):
        for (backend, n) in times:
            start = time.perf_counter()
            gens[backend].generate(text, lengths=196, seed=r, candidates=n)
            times[(backend, n)].append(1000 * (time.perf_counter() - start))
    print(f"generate('{text}'), 196 frames, 5 NFE, warm text, {args.threads} threads, "
          f"median of {args.repeat} (ms):")
    print(f"{'backend':<16}" + "".join(f"{'N=' + str(n):>12}" for n in counts))
    for backend in gens:
        base = statistics.median(times[(backend, counts[0])])
        cells = [statistics.median(times[(backend, n)]) for n in counts]
        print(f"{backend:<16}" + "".join(f"{c:>7.1f} {c / base:>3.1f}x" for c in cells))
    gen = next(iter(gens.values()))
    if gen.critic is not None:
        z = torch.randn(16, *gen.ae.latent_shape)
        cond = gen.encode_text([text])
        runs = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            gen.critic.best(z, torch.tensor([196]), cond, 16)
            runs.append(1000 * (time.perf_counter() - start))
        print(f"the critic scoring 16 latents: {statistics.median(runs):.2f} ms")


if __name__ == "__main__":
    main()
