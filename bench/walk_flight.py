"""Do a model's walks keep a foot on the floor? Level-walk prompts, a few seeds each, counted by
the clips that lift both feet above a clearance for more than 3 frames (eval/readouts.py's
airborne_frames, the read-out behind the everyday vocabulary's walk.no_flight), several models
side by side.

    python bench/walk_flight.py [--models bundled DIR ...] [--seeds 3]
"""

from __future__ import annotations

import argparse

import numpy as np

import mlct
from mlct.eval.readouts import airborne_frames

PROMPTS = ("a person walks forward", "a man walks forward slowly", "a woman walks in a circle",
           "a person walks to the left", "a person walks backward", "a tired man walks forward",
           "a person walks forward happily")
CLEARANCES_M = (0.02, 0.03, 0.04, 0.05)
FRAMES = 3  # more airborne frames than this make a clip "in flight"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument("--models", nargs="+", default=["bundled"])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    heading = " / ".join(f"{c * 100:.0f}" for c in CLEARANCES_M)
    print(f"{len(PROMPTS)} walk prompts x {args.seeds} seeds; clips with both feet up over "
          f"{FRAMES} frames at {heading} cm; median frames above {CLEARANCES_M[-1] * 100:.0f} cm")
    for model in args.models:
        pipe = mlct.load(None if model == "bundled" else model)
        counts = np.zeros(len(CLEARANCES_M), int)
        highest = []
        for prompt in PROMPTS:
            for seed in range(args.seeds):
                joints = pipe.generate(prompt, seed=seed * 100000)[0].joints
                counts += [airborne_frames(joints, c) > FRAMES for c in CLEARANCES_M]
                highest.append(airborne_frames(joints, CLEARANCES_M[-1]))
        print(f"{model}: {' / '.join(map(str, counts))} of {len(PROMPTS) * args.seeds}; "
              f"{np.median(highest):.0f}")


if __name__ == "__main__":
    main()
