"""How long should a clip be when nobody says? Three rules side by side on the hand-written
prompts of bench/data, scored by the read-outs as bench/motion_quality.py scores them.

    python bench/default_length.py [--model DIR] [--seeds 5]

Rules: a flat 5 s (mlct's default until 2026-11-27); "5 s or what the actions take"
(pipeline.default_seconds, the default since); the duration model's length alone
(`seconds="auto"`). Sets: the seen paraphrases, the three held-out sets and the two-action
prompts. Same seeds for every rule, in one run. Prints each set's pass rate per rule, the clip
lengths, and the prompts a rule passes less often than the flat 5 s.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import mlct
from motion_quality import PROMPTS, hand_written_sets, prompt_passes

FLAT = 5.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    prompts = json.loads(PROMPTS.read_text(encoding="utf-8"))
    sets = {**hand_written_sets(), "two actions": prompts["two_actions"]}
    pipe = mlct.load(args.model)
    print(f"model {args.model or 'bundled'}, {args.seeds} seeds; pass rate (clip seconds min / "
          f"median / max)")
    for name, items in sets.items():
        texts = [p["text"] for p in items]
        rules = {"flat 5 s": [FLAT] * len(texts),
                 "5 s or what the actions take": pipe.default_seconds(texts),
                 "duration model alone": pipe.auto_seconds(texts)}
        rates = {}
        cells = []
        for rule, seconds in rules.items():
            passed = prompt_passes(pipe, items, seconds, args.seeds) / args.seeds
            rates[rule] = passed
            cells.append(f"{rule}: {passed.mean():.3f} ({min(seconds):.1f} / "
                         f"{float(np.median(seconds)):.1f} / {max(seconds):.1f} s)")
        print(f"{name:17} " + " | ".join(cells))
        for rule in list(rules)[1:]:
            worse = [t for t, a, b in zip(texts, rates[rule], rates["flat 5 s"]) if a < b - 1e-9]
            if worse:
                print(f"{'':17}   {rule}, worse than flat 5 s: {worse}")


if __name__ == "__main__":
    main()
