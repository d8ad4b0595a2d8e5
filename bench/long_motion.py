"""Seams of long motions: are joint speeds where two segments meet within the segments' own?

    python bench/long_motion.py [--model MODEL_DIR] [--seeds 4] [--blend 0.75]

For a few chains of prompts and several seeds it generates the long motion (long_motion.py) and
prints the largest joint speed inside the seams' blend windows against the largest and the 99th
percentile speed of the segments as generated, with their ratio; the last line is the worst
ratio over all runs (at most 1 means every seam stays within its segments' range).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import mlct
from mlct.generate.long_motion import BLEND_SECONDS, generate_long, seam_speeds

CHAINS = [
    (["a person walks forward", "a person turns left", "a person jumps"], [3, 2, 2]),
    (["a person walks forward", "a person waves with the right hand",
      "a person walks backward"], [3, 3, 3]),
    (["a person runs", "a person squats", "a person raises both arms"], [2, 3, 2]),
    (["a person walks backward", "a person kicks with the left leg", "a person runs"], [2, 2, 2]),
    (["a person sits down and stands up", "a person walks forward", "a person bows"], [4, 3, 2]),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--nfe", type=int, default=5)
    parser.add_argument("--blend", type=float, default=BLEND_SECONDS, help="seconds")
    args = parser.parse_args()
    generator = mlct.load(args.model)
    generator.encode_text(["warm-up"])
    print(f"blend {args.blend} s, nfe {args.nfe}; speeds in m/s")
    print(f"{'chain':<58}{'seed':>5}{'seam max':>10}{'seg max':>9}{'seg p99':>9}{'ratio':>7}"
          f"{'ms':>7}")
    worst = 0.0
    for prompts, seconds in CHAINS:
        for seed in range(args.seeds):
            start = time.perf_counter()
            motion = generate_long(generator, prompts, seconds, args.nfe, seed, args.blend)
            ms = (time.perf_counter() - start) * 1000
            s = seam_speeds(motion)
            ratio = s["seam_max"] / s["segments_max"]
            worst = max(worst, ratio)
            label = " / ".join(p.removeprefix("a person ") for p in prompts)
            print(f"{label[:57]:<58}{seed:>5}{s['seam_max']:>10.2f}{s['segments_max']:>9.2f}"
                  f"{s['segments_p99']:>9.2f}{ratio:>7.2f}{ms:>7.0f}")
    print(f"worst seam max / segment max: {worst:.3f}")


if __name__ == "__main__":
    main()
