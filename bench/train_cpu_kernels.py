"""One stage-2 training step of the `small` preset on the CPU, with PyTorch's dropout and
for-loop AdamW (before 2026-11-28) against the CPU kernels the trainer now picks
(mlct.nn.dropout.CheapDropout's PCG64 masks, fused AdamW), each alone and both; one process,
the variants taking turns step by step so a busy machine hits all alike.

    python bench/train_cpu_kernels.py [--steps 12] [--threads 2] [--precision bf16|fp32]

The step is bench/train_speed.py's (`build_step`): batch 64 of synthetic motions and text
vectors of the real shapes through the frozen encoder, the consistency loss, the backward pass,
clipping and the update (what `mlct train cm` runs per step, without the data loader). Prints
the median ms per step and the gain over the first row.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from train_speed import build_step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=12)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--precision", default="bf16", choices=["bf16", "fp32"])
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    kinds = {"torch dropout, for-loop AdamW (before)": (False, False),
             "PCG64 dropout": (True, False), "fused AdamW": (False, True),
             "both (the trainer on a CPU now)": (None, None)}  # None: the trainer's own choice
    variants = {name: build_step("small", "cm", "cpu", args.precision, dropout, fused)[0]
                for name, (dropout, fused) in kinds.items()}
    for step in variants.values():
        step(), step()  # warm-up
    times: dict[str, list[float]] = {name: [] for name in variants}
    for _ in range(args.steps):
        for name, step in variants.items():
            start = time.perf_counter()
            step()
            times[name].append(time.perf_counter() - start)
    print(f"stage 2, small preset, batch 64, {args.precision}, {args.threads} threads, "
          f"{args.steps} steps each in turn; median ms per step")
    first = None
    for name, values in times.items():
        median = statistics.median(values) * 1000.0
        first = first or median
        print(f"  {name:40} {median:7.1f} ms  {first / median:4.2f}x")


if __name__ == "__main__":
    main()
