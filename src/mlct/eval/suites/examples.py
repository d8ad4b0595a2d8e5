"""Do five example prompts do what they say (a walk, a jog, two jumps, a walk then a wave, and
a chain of three prompts)? Each scored by the read-outs of its label, over a few seeds.

    python bench/quality.py examples [--model DIR] [--seeds 5]

Prints, per example, the checks and how many seeds pass all of them. The labels are written
here by hand from the prompts; the read-outs are the ones bench/quality.py motion uses.
"""

from __future__ import annotations

import argparse
from typing import Any

import mlct
from mlct.eval.readouts import evaluate_label


def action(family: str, start: float, end: float, **params: Any) -> dict[str, Any]:
    return {"family": family, "params": params, "start": start, "end": end}


# (the prompts, the seconds asked for, the label the motion must satisfy)
EXAMPLES: list[tuple[list[str], list[float], list[dict[str, Any]]]] = [
    (["a person walks forward"], [5.0], [action("walk", 0, 5)]),
    (["a man jogs straight ahead"], [5.0], [action("jog", 0, 5)]),
    (["a person jumps twice"], [5.0], [action("jump", 0, 5, mode="in_place", count=2)]),
    (["a person walks forward, then waves with the right hand"], [7.0], [
        action("walk", 0, 3.5), action("wave", 3.5, 7, hand="right")]),
    (["a person walks forward", "a person turns left", "a person squats"], [3.0, 2.0, 3.0], [
        action("walk", 0, 3), action("turn", 3, 5, side="left", angle=90),
        action("squat", 5, 8)]),
]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", default=None)
    parser.add_argument("--seeds", type=int, default=5)


def run(args: argparse.Namespace) -> None:
    gen = mlct.load(args.model)
    from mlct.generate.compose.long_motion import generate_long

    total = passed = 0
    for prompts, seconds, actions in EXAMPLES:
        label = {"actions": actions, "concurrent": None}
        results = []
        for seed in range(args.seeds):
            if len(prompts) == 1:
                motion = gen.generate(prompts[0], seconds=seconds[0], seed=seed)[0]
            else:
                motion = generate_long(gen, prompts, seconds, seed=seed)
            results.append(evaluate_label(motion.joints, label))
        ok = [all(p for _, p in r) for r in results]
        failed = sorted({name for r in results for name, p in r if not p})
        total += len(ok)
        passed += sum(ok)
        print(f"{sum(ok)}/{len(ok)}  {' / '.join(prompts)}"
              + (f"   (failed: {', '.join(failed)})" if failed else ""))
    print(f"all: {passed}/{total} = {passed / total:.2f}")
