"""How much latent noise an autoencoder's decoding survives, per family, side by side.

    python bench/latent_robustness.py --data SYNTH --ae RUN [RUN ...] [--noise 0,0.067,0.133]
        [--seed 0] [--json OUT]

Each single-action test motion is encoded, its latent perturbed by noise * N(0, I) (the
autoencoder's own units: the quantized latent lies in [-1, 1]; stage 2 sees it times
schedule.latent_scale), decoded, and scored by the read-outs of bench/motion_quality.py. Why:
a stage-2 sample is never exactly a real motion's latent, and a decoder whose fine detail
carries an action (a clap's hand meetings, a wave's sway) turns that error into a damped
version of it. Same noise draws for every run (--seed), so the columns compare.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import evaluate_label
from mlct.motion.features import features_to_joints

sys.path.insert(0, str(Path(__file__).parent))
from motion_quality import MAX_FRAMES, reconstruct  # noqa: E402


def pass_rates(run: Path, features: list[np.ndarray], labels: list[dict], noise: float,
               seed: int) -> dict[str, float]:
    """Per family and overall: the share of the motions whose perturbed reconstruction passes."""
    torch.manual_seed(seed)  # the same noise draws for every run of the same latent shape
    tally: dict[str, list[int]] = defaultdict(lambda: [0, 0])
    for made, label in zip(reconstruct(run, features, noise), labels):
        ok = all(p for _, p in evaluate_label(features_to_joints(made), label))
        for key in (label["actions"][0]["family"], "OVERALL"):
            tally[key][0] += ok
            tally[key][1] += 1
    return {k: v[0] / v[1] for k, v in sorted(tally.items())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", required=True)
    parser.add_argument("--ae", nargs="+", required=True, type=Path, metavar="RUN")
    parser.add_argument("--noise", default="0,0.067,0.133")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    names = [n for n in layout.read_split("test") if n in labels
             and len(labels[n]["actions"]) == 1 and not labels[n].get("concurrent")]
    levels = [float(v) for v in args.noise.split(",")]
    features = [layout.load_features(n)[:MAX_FRAMES] for n in names]
    chosen = [labels[n] for n in names]
    columns = {f"{run.name} @{noise:g}": pass_rates(run, features, chosen, noise, args.seed)
               for run in args.ae for noise in levels}
    print(f"{len(names)} single-action test motions of {args.data}; pass rate of the "
          f"reconstruction with latent noise (autoencoder units)")
    print(f"{'family':<16}" + "".join(f"{c:>16}" for c in columns))
    for family in next(iter(columns.values())):
        print(f"{family:<16}" + "".join(f"{c[family]:>16.2f}" for c in columns.values()))
    if args.json:
        args.json.write_text(json.dumps(columns, indent=1) + "\n")


if __name__ == "__main__":
    main()
