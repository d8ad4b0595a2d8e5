"""The plainest sided prompts, left and right, for every family that has a side: does a model
keep the side it is told?

    python bench/sided_prompts.py [--models bundled DIR ...] [--seeds 5]

The benchmark's "named side" figure averages every sided caption, so a model that always kicks
with its right leg can still pass it (left kicks are a twentieth of the sided captions). Here
each family's side is asked on its own in the benchmark's plainest words ("a person kicks with
the left leg"), at the pipeline's default length, the same seeds for every model, and scored by
the read-outs (motion_quality.judge_prompt). Prints, per model, the passes of each prompt and
the families whose left or right side passes fewer than half of its seeds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mlct
from motion_quality import judge_prompt

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


def items() -> list[tuple[str, dict]]:
    """(prompt, action) for every family and side."""
    return [(text.format(side=side), {"family": family, "params": {key: side, **fixed}})
            for family, key, text, fixed in PROMPTS for side in SIDES]


def passes(pipe, seeds: int) -> list[int]:
    """How many of `seeds` samples of each prompt pass all its checks."""
    prompts = items()
    texts = [text for text, _ in prompts]
    seconds = pipe.default_seconds(texts)
    counts = [0] * len(prompts)
    for seed in range(seeds):
        made = pipe.generate(texts, seconds=seconds, seed=seed * 100_000)
        for i, ((_, action), motion) in enumerate(zip(prompts, made)):
            _, results = judge_prompt(motion.joints, [action],
                                      motion.joints.shape[0] / pipe.skeleton.fps)
            counts[i] += all(ok for _, ok in results)
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", nargs="+", default=["bundled"])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    prompts = items()
    table = {name: passes(mlct.load(None if name == "bundled" else Path(name)), args.seeds)
             for name in args.models}
    print(f"{args.seeds} seeds at the default length; passes per prompt, models in the order "
          f"{', '.join(args.models)}")
    for i, (text, _) in enumerate(prompts):
        print(f"  {' | '.join(f'{table[m][i]}/{args.seeds}' for m in args.models)}  {text}")
    for name, counts in table.items():
        weak = [text for (text, _), n in zip(prompts, counts) if 2 * n < args.seeds]
        print(f"{name}: all {sum(counts) / (len(counts) * args.seeds):.3f}; a side under half "
              f"its seeds: {len(weak)}{' (' + '; '.join(weak) + ')' if weak else ''}")


if __name__ == "__main__":
    main()
