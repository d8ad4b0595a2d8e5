"""seconds="auto": do prompts do what they say more often when the clip's length comes from the
text (the model's duration model) instead of one length for every prompt?

bench/motion_quality.py makes each hand-written paraphrase in 4 s and each two-action prompt in
7 s; `generate` without a length makes 5 s. Some actions do not fit: a circle walked at the
data's pace takes ~7.5 s, so in 4 s it turns ~215 degrees and fails. This makes the same
prompts at the bench's length, at 5 s and at "auto", same seeds, one run, and prints the
read-out pass rates side by side, with the lengths "auto" chose. Two-action prompts
are judged as bench/motion_quality.py judges them: in order, at the motion's own cut, and (the
"halves" row) in equal halves, which also judges where the cut falls.

    python bench/auto_length.py [--model DIR] [--seeds 5]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import mlct
from motion_quality import HELDOUT, PROMPTS, Tally, judge_prompt


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
    print(f"{'prompts':<16}{'n':>5}{'bench':>10}{'5 s':>10}{'auto':>10}   auto seconds "
          "(median, range)")
    families: dict[str, list[int]] = {}
    for title, (items, fixed) in sets.items():
        texts = [p["text"] for p in items]
        auto = gen.auto_seconds(texts)
        modes = {"fixed": fixed, "5 s": 5.0, "auto": auto}
        tallies = {m: Tally() for m in modes}
        halves = {m: Tally() for m in modes}
        for seed in range(args.seeds):
            for mode, seconds in modes.items():
                out = gen.generate(texts, seconds=seconds, seed=seed * 100_000)
                for item, motion in zip(items, out):
                    clip_seconds = motion.joints.shape[0] / gen.skeleton.fps
                    ok = tallies[mode].add(*judge_prompt(motion.joints, item["actions"],
                                                         clip_seconds))
                    if len(item["actions"]) > 1:
                        halves[mode].add(*judge_prompt(motion.joints, item["actions"],
                                                       clip_seconds, halves=True))
                    if len(item["actions"]) == 1:
                        key = item["actions"][0]["family"]
                        counts = families.setdefault(key, dict.fromkeys((*modes, "n"), 0))
                        counts[mode] += ok
                        counts["n"] += mode == "fixed"
        rates = "".join(f"{tallies[m].summary()['overall']:>10.3f}" for m in modes)
        print(f"{title:<16}{len(items):>5}{rates}   "
              f"{np.median(auto):.1f} s ({min(auto):.1f}-{max(auto):.1f}; bench {fixed:g} s)")
        if halves["fixed"].motions[1]:
            rates = "".join(f"{halves[m].summary()['overall']:>10.3f}" for m in modes)
            print(f"{'  ... halves':<16}{len(items):>5}{rates}")
    print("\none-action paraphrases by family (seen and held-out): 4 s / 5 s / auto")
    for family, counts in sorted(families.items()):
        n = counts["n"]
        print(f"  {family:<14} " + " / ".join(f"{counts[m]:>3}/{n:<3}" for m in modes))


if __name__ == "__main__":
    main()
