"""The hand-written one-action prompt sets, several models side by side in one run.

    python bench/quality.py paraphrases [--models bundled DIR ...] [--seeds 5] [--failures SET]
        [--sets "held-out 5" ...]

A model given as NAME@MARGIN runs with that critic margin (bundled@0: the best of N), so that
margins compare side by side.

Sets (bench/data): the seen paraphrases, held-out 1 to 7 (--sets: only those named). Each
prompt is made at 4 s (as bench/quality.py motion's columns) and at the pipeline's default
length (what a user gets who gives none), the same seeds for every model, scored by the
read-outs (common.judge_prompt).
Prints per model and set: the pass rate at both lengths and, for the prompts that name a side or
turn direction, that rate at 4 s; then, for --failures SET (default held-out 3), each prompt
some model fails in some seed, with every model's pass counts and the checks that failed (how
many seeds each, at 4 s and at the default length).
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

import mlct
from mlct.eval.suites.common import (SIDE_KEYS, hand_written_sets, prompt_passes,
                                     set_critic_margin)

SECONDS = 4.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--models", nargs="+", default=["bundled"],
                        help="model folders or 'bundled', each maybe NAME@MARGIN")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--failures", default="held-out 3")
    parser.add_argument("--sets", nargs="+", default=None,
                        help="only these sets, e.g. 'held-out 5' (default: all)")


def run(args: argparse.Namespace) -> None:
    sets = hand_written_sets(args.prompt_dir)
    if args.sets is not None:
        unknown = sorted(set(args.sets) - set(sets))
        if unknown:
            args.error(f"unknown set {unknown[0]!r}; the sets: {', '.join(sets)}")
        sets = {name: items for name, items in sets.items() if name in args.sets}
    results: dict[str, dict[str, dict[str, np.ndarray]]] = {}
    print(f"{args.seeds} seeds; pass rate at 4 s | at the default length | named side at 4 s")
    for name in args.models:
        model, _, margin = name.rpartition("@") if "@" in name else (name, "", "")
        try:
            value = float(margin) if margin else None
        except ValueError:
            args.error(f"{name!r}: the margin after '@' must be a number")
        pipe = mlct.load(None if model == "bundled" else Path(model))
        set_critic_margin(pipe, value)
        results[name] = {}
        for set_name, items in sets.items():
            texts = [p["text"] for p in items]
            failed4, failed_auto = [Counter() for _ in items], [Counter() for _ in items]
            at4 = prompt_passes(pipe, items, [SECONDS] * len(items), args.seeds, failed4)
            auto = prompt_passes(pipe, items, pipe.default_seconds(texts), args.seeds,
                                 failed_auto)
            sided = np.array([any(k in a["params"] for a in p["actions"] for k in SIDE_KEYS)
                              for p in items])
            results[name][set_name] = {"4 s": at4, "default": auto, "failed 4 s": failed4,
                                       "failed default": failed_auto}
            print(f"{name:40} {set_name:11} {at4.sum() / (len(items) * args.seeds):.3f} | "
                  f"{auto.sum() / (len(items) * args.seeds):.3f} | "
                  f"{at4[sided].sum() / max(1, sided.sum() * args.seeds):.3f} "
                  f"({len(items)} prompts, {int(sided.sum())} sided)", flush=True)
    if args.failures in sets:
        print(f"\n{args.failures}: prompts some model fails (passes of {args.seeds} at 4 s / "
              f"at the default length; models in the order {', '.join(args.models)})")
        for i, item in enumerate(sets[args.failures]):
            cells = [(int(results[m][args.failures]["4 s"][i]),
                      int(results[m][args.failures]["default"][i])) for m in args.models]
            if any(c != (args.seeds, args.seeds) for c in cells):
                print("  " + " | ".join(f"{a}/{b}" for a, b in cells) + f"  {item['text']}")
                for m in args.models:
                    print(f"        {m}: 4 s {checks(results[m][args.failures]['failed 4 s'][i])}"
                          f"; default {checks(results[m][args.failures]['failed default'][i])}")


def checks(failed: Counter) -> str:
    """'circle.heading 5, circle.path 3': each failed check and in how many seeds."""
    return ", ".join(f"{name.split(':', 1)[-1]} {n}" for name, n in failed.most_common()) or "-"
