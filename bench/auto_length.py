"""seconds="auto": do prompts do what they say more often when the clip's length comes from the
text (the model's duration model) instead of one length for every prompt?

bench/motion_quality.py makes each hand-written paraphrase in 4 s and each two-action prompt in
7 s. Some actions do not fit: a circle walked at the data's pace takes ~7.5 s, so in 4 s it
turns ~215 degrees and fails. This makes the same prompts both ways, same seeds, one run, and
prints the read-out pass rates side by side, with the lengths "auto" chose.

    python bench/auto_length.py [--model DIR] [--seeds 5]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import mlct
from mlct.eval.readouts import evaluate_label

from motion_quality import HELDOUT, PROMPTS, Tally, prompt_label


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    gen = mlct.load(args.model, backend="torch")
    prompts = json.loads(PROMPTS.read_text(encoding="utf-8"))
    sets = {"paraphrases": (prompts["paraphrases"], 4.0),
            "held-out para": (json.loads(HELDOUT.read_text(encoding="utf-8"))["paraphrases"],
                              4.0),
            "two actions": (prompts["two_actions"], 7.0)}
    print(f"model {args.model or 'bundled'}; {args.seeds} seeds; read-out pass rates")
    print(f"{'prompts':<16}{'n':>5}{'fixed':>10}{'auto':>10}   auto seconds (median, range)")
    families: dict[str, list[int]] = {}
    for title, (items, fixed) in sets.items():
        texts = [p["text"] for p in items]
        auto = gen.auto_seconds(texts)
        tallies = {"fixed": Tally(), "auto": Tally()}
        for seed in range(args.seeds):
            for mode, seconds in (("fixed", fixed), ("auto", auto)):
                out = gen.generate(texts, seconds=seconds, seed=seed * 100_000)
                for item, motion in zip(items, out):
                    label = prompt_label(item["actions"], motion.joints.shape[0] / gen.skeleton.fps)
                    ok = tallies[mode].add(label, evaluate_label(motion.joints, label))
                    if len(item["actions"]) == 1:
                        key = item["actions"][0]["family"]
                        counts = families.setdefault(key, [0, 0, 0])
                        counts[0 if mode == "fixed" else 1] += ok
                        counts[2] += mode == "fixed"
        fixed_rate, auto_rate = (tallies[m].summary()["overall"] for m in ("fixed", "auto"))
        print(f"{title:<16}{len(items):>5}{fixed_rate:>10.3f}{auto_rate:>10.3f}   "
              f"{np.median(auto):.1f} s ({min(auto):.1f}-{max(auto):.1f}; fixed {fixed:g} s)")
    print("\none-action paraphrases by family (seen and held-out): fixed 4 s -> auto")
    for family, (fixed_ok, auto_ok, n) in sorted(families.items()):
        print(f"  {family:<14} {fixed_ok:>3}/{n:<3} -> {auto_ok:>3}/{n}")


if __name__ == "__main__":
    main()
