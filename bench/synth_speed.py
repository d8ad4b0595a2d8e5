"""Procedural benchmark speed: motions per second on one core, and a 10,000-motion projection.

    python bench/synth_speed.py [--num 300] [--skeleton humanml3d]

Prints the rate of the whole `mlct data synth` path (script, poses, ground contact, standard
feature processing, recovery of new_joints, captions, file writes, Mean/Std) on one process with
one torch thread, and of its parts. The goal: >= 50 motions/s on one core.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np
import torch

from mlct.data.synth.build import make_motion, synthesize_dataset
from mlct.data.synth.compose import compose
from mlct.data.synth.actions import sample_script
from mlct.data.synth.motions import Style
from mlct.data.synth.rig import make_rig
from mlct.motion.skeleton import get_skeleton


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num", type=int, default=300)
    parser.add_argument("--skeleton", default="humanml3d")
    args = parser.parse_args()
    torch.set_num_threads(1)
    skeleton = get_skeleton(args.skeleton)
    rig = make_rig(skeleton)

    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for _ in range(args.num):
        compose(sample_script(rng), rig, Style(), rng, skeleton.fps)
    compose_rate = args.num / (time.perf_counter() - start)

    start = time.perf_counter()
    for index in range(args.num):
        make_motion(index, 0, skeleton)
    motion_rate = args.num / (time.perf_counter() - start)

    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        summary = synthesize_dataset(f"{tmp}/data", num=args.num, seed=0, skeleton=skeleton,
                                     progress=False)
        total = time.perf_counter() - start
    rate = args.num / total
    print(f"skeleton {skeleton.name}, {args.num} motions, 1 process, 1 torch thread")
    print(f"  poses + ground contact only : {compose_rate:8.1f} motions/s")
    print(f"  + features, joints, captions: {motion_rate:8.1f} motions/s")
    print(f"  full synth incl. writes     : {rate:8.1f} motions/s "
          f"({summary['frames'] / total:,.0f} frames/s), goal 50 -> {rate / 50:.2f}x")
    print(f"  10,000 motions would take   : {10_000 / rate / 60:8.1f} min on one core")
    print(f"  foot-skating ratio (mean)   : {summary['skating_ratio']:8.4f}")


if __name__ == "__main__":
    main()
