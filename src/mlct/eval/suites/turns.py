"""How far a turn turns: the heading change of turn and spin prompts, several models side by side.

    python bench/quality.py turns [--models bundled DIR ...] [--seeds 5] [--seconds 4]
                               [--also "PROMPT@DEGREES" ...] [--only-also]

The read-outs pass a turn within a band around its size, so a model whose turns all shrink by a
third can still pass most of them; this prints the angles themselves. Each prompt below has the
size the benchmark's convention gives it (a bare "turns left" is a quarter turn, as in the
benchmark's captions; a spin is a whole one), in degrees, positive to the person's left. For
each model and prompt: the heading change of every seed, and the median of |turned - size|;
then per model the median and the mean of that error over all prompts and seeds, and the share
of turns within 30 degrees of their size. `--also` adds prompts of one's own (their size after
the "@", positive to the left), `--only-also` runs just those. A fine-tune that pulls turns
towards smaller angles (docs/training.md) shows here first.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import mlct
from mlct.eval.readouts import heading_change

# (prompt, size in degrees, positive = left): plain, numeric, sized in words, vague
PROMPTS: tuple[tuple[str, float], ...] = (
    ("a person turns left", 90),
    ("a person turns right", -90),
    ("a person turns 90 degrees to the right", -90),
    ("a person turns 45 degrees to the left", 45),
    ("a person turns 180 degrees to the left", 180),
    ("a person turns around to the right", -180),
    ("a man makes a quarter turn to the left", 90),
    ("a woman makes a half turn to the right", -180),
    ("a man changes direction, turning ninety degrees left", 90),
    ("someone pivots on the spot towards the right", -90),
    ("a person spins around to the left", 360),
    ("someone does a complete rotation to the right on the spot", -360),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--models", nargs="+", default=["bundled"])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--also", action="append", default=[], metavar="PROMPT@DEGREES",
                        help="another prompt and its size in degrees, positive = left")
    parser.add_argument("--only-also", action="store_true", help="only the --also prompts")


def run(args: argparse.Namespace) -> None:
    try:
        extra = [(text, float(size)) for text, _, size in
                 (item.rpartition("@") for item in args.also)]
        if any(not text for text, _ in extra):
            raise ValueError("no prompt before the '@'")
    except ValueError:
        args.error("--also takes PROMPT@DEGREES, e.g. 'a person turns left@90'")
    prompts = extra if args.only_also else [*PROMPTS, *extra]
    if not prompts:
        args.error("--only-also needs at least one --also")
    errors: dict[str, list[float]] = {}
    print(f"{args.seeds} seeds at {args.seconds:g} s; degrees turned (positive = left) and the "
          f"median |error| against the size")
    for name in args.models:
        pipe = mlct.load(None if name == "bundled" else Path(name))
        errors[name] = []
        print(f"\n{name}")
        for text, size in prompts:
            turned = np.array([np.degrees(heading_change(pipe.generate(
                [text], seconds=args.seconds, seed=seed)[0].joints))
                for seed in range(args.seeds)])
            error = np.abs(turned - size)
            errors[name].extend(error.tolist())
            print(f"  {size:5.0f}  {np.median(error):5.0f}  "
                  f"[{' '.join(f'{t:5.0f}' for t in turned)}]  {text}", flush=True)
    print("\nmodel                                    median |error|  mean |error|  within 30 deg")
    for name, errs in errors.items():
        e = np.array(errs)
        print(f"{name:40} {np.median(e):14.1f} {e.mean():13.1f} {np.mean(e <= 30):14.3f}")
