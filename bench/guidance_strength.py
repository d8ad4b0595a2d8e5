"""How far decoder guidance alone brings a walk toward a path: the test's measure
(tests/test_control.py), over more seeds and several models side by side.

    MLCT_BACKEND=torch python bench/guidance_strength.py [--models bundled DIR ...] [--seeds 30]

For each seed, "a person walks forward" (120 frames) is made with guidance and without (no
projection, one candidate, the same seed), and the mean distance of the root from the path's
waypoints with guidance is divided by that without. Printed per model: the mean, median and
standard error of that ratio. 1 means guidance did nothing; the test asks for a 6-seed mean
under 1, and one seed's ratio ranges from about 0.2 to 1.6, so compare models on 30 seeds.
Guidance needs the torch backend (its gradients run through the torch decoder).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

import numpy as np

import mlct
from mlct.generate.control import control_from_dict
from mlct.generate.controlled import ControlMethod, generate_controlled

PATH = [[0.0, 0.0, 0], [0.2, 1.2, 40], [0.9, 2.2, 80], [1.9, 2.6, 119]]  # the test's path
FRAMES = 120


def ratios(pipe: Any, seeds: int) -> np.ndarray:
    control = control_from_dict({"path": PATH}, pipe.skeleton).check(FRAMES, pipe.skeleton)
    frames, target = [p[2] for p in PATH], np.array(PATH)[:, :2]

    def error(guide: bool, seed: int) -> float:
        made = generate_controlled(pipe, "a person walks forward", FRAMES, control, None, seed,
                                   ControlMethod(guide=guide, project=False, candidates=1))
        return float(np.linalg.norm(made.joints[frames, 0][:, [0, 2]] - target, axis=1).mean())
    return np.array([error(True, s) / error(False, s) for s in range(seeds)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", nargs="+", default=["bundled"])
    parser.add_argument("--seeds", type=int, default=30)
    args = parser.parse_args()
    if os.environ.get("MLCT_BACKEND", "auto") != "torch":
        parser.error("run with MLCT_BACKEND=torch: guidance needs the torch backend")
    print(f"guided / plain path error, {args.seeds} seeds (seed 0 first)")
    print(f"{'model':40} {'mean':>6} {'median':>7} {'s.e.':>6} {'first 6':>8}")
    for name in args.models:
        r = ratios(mlct.load(None if name == "bundled" else Path(name)), args.seeds)
        print(f"{name:40} {r.mean():6.3f} {np.median(r):7.3f} "
              f"{r.std() / np.sqrt(len(r)):6.3f} {r[:6].mean():8.3f}", flush=True)


if __name__ == "__main__":
    main()
