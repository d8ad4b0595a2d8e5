"""Motions per second of generate() on a list of prompts, with the samples made ahead in a few
large batches (generate/batch_plan.py) and without (each prompt's path on its own, as before).

    python bench/batched_prompts.py [--batch 64] [--rounds 3] [--candidates 1,8]
                                    [--backends auto,torch] [--model DIR]

Workloads, each a list of `--batch` prompts (cycled from bench/data's hand-written sets):
plain one-action prompts at 4 s; two-action sequences at 7 s; an arm action during a walk
("while waving") at 5 s; gaits at 9.8 s that keep going (takes chained). The two ways take
turns, round by round, on one loaded generator per backend, so the machine's drift hits both;
the figure is the median over rounds of motions per second for the whole generate() call, feet
planted, as a user gets them. The motions of the two ways agree within float rounding
(tests/test_batch_plan.py), so only the time is compared.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from itertools import cycle, islice
from pathlib import Path

import torch

import mlct

DATA = Path(__file__).resolve().parent / "data"
WHILE = ["a person walks forward while waving the right hand",
         "a man walks forward while clapping", "someone jogs forward while waving the left hand",
         "a woman walks backwards while waving"]
GAITS = ["a person walks forward", "a person jogs forward", "someone runs forward",
         "a man walks backwards", "a person walks in a circle to the left"]


def workloads(batch: int) -> dict[str, tuple[list[str], float]]:
    prompts = json.loads((DATA / "quality_prompts.json").read_text(encoding="utf-8"))
    plain = [p["text"] for p in prompts["paraphrases"]]
    two = [p["text"] for p in prompts["two_actions"]]

    def take(items: list[str]) -> list[str]:
        return list(islice(cycle(items), batch))
    return {"plain, 4 s": (take(plain), 4.0), "two actions, 7 s": (take(two), 7.0),
            "while waving, 5 s": (take(WHILE), 5.0), "gaits kept going, 9.8 s": (take(GAITS), 9.8)}


def timed(generator, texts: list[str], seconds: float, candidates: int, ahead: bool) -> float:
    generator.make_ahead = ahead
    try:
        start = time.perf_counter()
        generator.generate(texts, seconds=seconds, seed=0, candidates=candidates)
        return time.perf_counter() - start
    finally:
        generator.make_ahead = True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--candidates", default="1,8")
    parser.add_argument("--backends", default="auto,torch")
    parser.add_argument("--model", default=None)
    parser.add_argument("--threads", type=int, default=None)
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"generate() on lists of {args.batch} prompts, {torch.get_num_threads()} threads; "
          f"motions/s, median of {args.rounds} rounds taking turns (min-max)")
    print(f"{'backend':8} {'workload':26} {'cand':>4} {'one path at a time':>24} "
          f"{'made ahead':>24} {'ratio':>6}")
    for backend in args.backends.split(","):
        generator = mlct.load(args.model, backend=backend)
        for name, (texts, seconds) in workloads(args.batch).items():
            for candidates in (int(c) for c in args.candidates.split(",")):
                for ahead in (False, True):  # warm: the text memo, the networks of each size
                    timed(generator, texts, seconds, candidates, ahead)
                rates: dict[bool, list[float]] = {False: [], True: []}
                for _ in range(args.rounds):
                    for ahead in (False, True):
                        rates[ahead].append(len(texts) / timed(generator, texts, seconds,
                                                               candidates, ahead))

                def cell(values: list[float]) -> str:
                    return (f"{statistics.median(values):7.1f} ({min(values):.0f}-"
                            f"{max(values):.0f})")
                ratio = statistics.median(rates[True]) / statistics.median(rates[False])
                print(f"{generator.backend:8} {name:26} {candidates:4d} {cell(rates[False]):>24} "
                      f"{cell(rates[True]):>24} {ratio:5.2f}x", flush=True)


if __name__ == "__main__":
    main()
