"""The plainest sided prompts, left and right, for every family that has a side: does a model
keep the side it is told?

    python bench/quality.py sides [--models bundled DIR ...] [--seeds 5]

The benchmark's "named side" figure averages every sided caption, so a model that always kicks
with its right leg can still pass it (left kicks are a twentieth of the sided captions). Here
each family's side is asked on its own in the benchmark's plainest words ("a person kicks with
the left leg"), at the pipeline's default length, the same seeds for every model, and scored by
the read-outs (common.prompt_passes). Prints, per model, the passes of each prompt and
the families whose left or right side passes fewer than half of its seeds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mlct
from mlct.eval.suites.common import prompt_passes

# (family, the side's key, the prompt with {side}, other fixed params)
PROMPTS = [
    ("side_step", "side", "a person steps to the {side}", {}),
    ("turn", "side", "a person turns {side}", {"angle": 90}),
    ("circle", "side", "a person walks in a circle to the {side}", {}),
    ("spin", "side", "a person spins around to the {side}", {}),
    ("hop", "leg", "a person hops on the {side} foot", {}),
    ("kneel", "leg", "a person kneels on the {side} knee and stands up", {}),
    ("wave", "hand", "a person waves with the {side} hand", {}),
    ("raise_arms", "hand", "a person raises the {side} arm", {}),
    ("punch", "hand", "a person punches with the {side} hand", {}),
    ("kick", "leg", "a person kicks with the {side} leg", {}),
]
SIDES = ("left", "right")


def items() -> list[dict]:
    """One hand-written prompt per family and side, as the motion suite.s sets hold them."""
    return [{"text": text.format(side=side),
             "actions": [{"family": family, "params": {key: side, **fixed}}]}
            for family, key, text, fixed in PROMPTS for side in SIDES]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--models", nargs="+", default=["bundled"])
    parser.add_argument("--seeds", type=int, default=5)


def run(args: argparse.Namespace) -> None:
    prompts = items()
    texts = [p["text"] for p in prompts]
    table = {}
    for name in args.models:
        pipe = mlct.load(None if name == "bundled" else Path(name))
        table[name] = prompt_passes(pipe, prompts, pipe.default_seconds(texts), args.seeds)
    print(f"{args.seeds} seeds at the default length; passes per prompt, models in the order "
          f"{', '.join(args.models)}")
    for i, text in enumerate(texts):
        print(f"  {' | '.join(f'{table[m][i]}/{args.seeds}' for m in args.models)}  {text}")
    for name, counts in table.items():
        weak = [text for text, n in zip(texts, counts) if 2 * n < args.seeds]
        print(f"{name}: all {sum(counts) / (len(counts) * args.seeds):.3f}; a side under half "
              f"its seeds: {len(weak)}{' (' + '; '.join(weak) + ')' if weak else ''}")
