"""How well a model's critic picks among its own candidates, judged by the read-outs.

    python bench/critic_ranking.py --data SYNTH --models DIR [DIR ...] [--split test]
                                   [--samples 8] [--seeds 1 2 3]

The first model samples K candidates for one caption of each one-action motion of the split at
its length (train/critic_samples.py: the seeds best-of-N uses), and the benchmark's read-outs
judge each. For the motions whose candidates disagree, each model's critic (the models must
share the first one's stage 2 and autoencoder: e.g. one critic trained with `--samples`, one
without) picks one: how often its pick passes, against a candidate drawn at random and the
first (plain sampling).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

import mlct
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import evaluate_label
from mlct.train.critic_samples import (SampledFoils, base_rate, ranking_accuracy,
                                      sample_foils)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--models", type=Path, nargs="+", required=True)
    parser.add_argument("--split", default="test")
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                        help="sampling seeds: each draws its own candidates; rows pooled")
    args = parser.parse_args()
    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    first = mlct.load(args.models[0], backend="torch")
    sets = [sample_foils(args.models[0], layout, layout.read_split(args.split), labels,
                         args.samples, seed, first.max_frames, evaluate_label,
                         log=lambda _: None)
            for seed in args.seeds]
    foils = SampledFoils(torch.cat([f.text for f in sets]), torch.cat([f.latents for f in sets]),
                         torch.cat([f.frames for f in sets]), torch.cat([f.passed for f in sets]),
                         {})
    print(f"{args.split}: {sets[0].info['motions_sampled']} one-action motions x "
          f"{args.samples} candidates, sampling seeds {args.seeds}: "
          f"{', '.join(str(len(f.passed)) for f in sets)} motions whose candidates disagree")
    print(f"  a random candidate passes {base_rate(foils):.3f}; the first (plain sampling) "
          f"{float(foils.passed[:, 0].float().mean()):.3f}")
    for model in args.models:
        critic = mlct.load(model, backend="torch").critic
        if critic is None:
            print(f"  {model}: no critic")
            continue
        info = critic.info.get("training", {})
        how = (f"samples {info['samples']['samples']}, seed {info['seed']}" if "samples" in info
               else "data only")
        each = ", ".join(f"{ranking_accuracy(critic.network, f):.3f}" for f in sets)
        print(f"  {model} ({how}): its best passes {ranking_accuracy(critic.network, foils):.3f}"
              f" (per seed: {each})")


if __name__ == "__main__":
    main()
