"""Where the onnx backend should hand a batch to the torch networks: sampling + decoding time
per motion at several batch sizes, ONNX Runtime against the torch networks, in one run.

    python bench/batch_handoff.py [--model DIR] [--batches 1,2,4,8,16,64] [--rounds 5]

Both are timed through the same OnnxMotionGenerator (its torch_min_batch set to 1 for torch, to
None for ONNX Runtime), round by round in turn so that a busy machine slows both alike; 196
frames, the default NFE, text embeddings memoized. Prints the median ms per motion and the
ratio; TORCH_MIN_BATCH (generate/onnx_backend.py) should be the first size where torch wins.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

import mlct
from mlct.generate.onnx_backend import TORCH_MIN_BATCH, OnnxMotionGenerator


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--batches", default="1,2,4,8,16,64")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    gen = mlct.load(args.model, backend="auto")
    if not isinstance(gen, OnnxMotionGenerator):
        raise SystemExit(f"the auto backend is not onnx here ({gen.backend_note})")
    batches = [int(b) for b in args.batches.split(",")]
    texts = ["a person walks forward", "a person jumps twice", "someone waves the left hand"]
    times: dict[tuple[str, int], list[float]] = {}
    for b in batches:
        cond = gen.encode_text((texts * b)[:b])
        for _ in range(args.rounds + 2):  # two warm-up rounds: graphs built, threads up
            for name, threshold in (("onnx", None), ("torch", 1)):
                gen.torch_min_batch = threshold
                start = time.perf_counter()
                gen.sample_features(cond, None, list(range(b)), None, [196] * b)
                times.setdefault((name, b), []).append(1000 * (time.perf_counter() - start) / b)
    print(f"sampling + decoding, 196 frames, default NFE, {args.threads} threads, median of "
          f"{args.rounds} rounds, ms per motion (TORCH_MIN_BATCH now {TORCH_MIN_BATCH}):")
    print(f"{'batch':>6} {'onnx':>8} {'torch':>8} {'onnx/torch':>11}")
    for b in batches:
        onnx, tch = (statistics.median(times[(n, b)][2:]) for n in ("onnx", "torch"))
        print(f"{b:>6} {onnx:>8.2f} {tch:>8.2f} {onnx / tch:>10.2f}x")


if __name__ == "__main__":
    main()
