"""Semantic accuracy of a model on the procedural benchmark: does each prompt's motion show the
actions the prompt asks for, per action family, judged by the action classifier?

    mlct train classifier --data synth --out cls          # once (about 5 min on a CPU)
    python bench/semantic_accuracy.py [--model MODEL_DIR] --data synth --classifier cls

For every motion of the split it generates one motion from its first caption, at the real
motion's length, and prints per class: the recall on generated motions next to the recall on
the real motions (the classifier's own ceiling), with the exact-set accuracy and mean recall of
both. The default model is the bundled one. --json OUT keeps the figures.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import mlct
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import (action_targets, load_action_classifier, read_labels,
                                               semantic_accuracy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--classifier", type=Path, required=True)
    parser.add_argument("--split", default="test")
    parser.add_argument("--nfe", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()

    generator = mlct.load(args.model)
    classifier = load_action_classifier(args.classifier)
    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    names = [n for n in layout.read_split(args.split) if n in labels]
    real = [layout.load_features(n) for n in names]
    captions = [layout.read_texts(n)[0].caption for n in names]
    targets = [action_targets(labels[n]) for n in names]

    start = time.perf_counter()
    lengths = [min(len(r), generator.max_frames) for r in real]
    made = generator.generate(captions, lengths=lengths, nfe=args.nfe, seed=args.seed)
    seconds = time.perf_counter() - start
    generated = semantic_accuracy(classifier, [m.features for m in made], targets)
    reference = semantic_accuracy(classifier, real, targets)

    print(f"{len(names)} motions of the {args.split} split; generated in {seconds:.1f} s "
          f"(nfe {generator.check_nfe(args.nfe)}, seed {args.seed})")
    print(f"{'class':<22}{'support':>8}{'generated':>11}{'real':>8}")
    for name in sorted(reference["recall"]):
        print(f"{name:<22}{reference['support'][name]:>8}"
              f"{generated['recall'].get(name, 0.0):>11.2f}{reference['recall'][name]:>8.2f}")
    for key in ("exact_set_accuracy", "mean_recall"):
        print(f"{key:<30}{generated[key]:>11.3f}{reference[key]:>8.3f}")
    if args.json:
        args.json.write_text(json.dumps({"generated": generated, "real": reference,
                                         "model": str(args.model or "bundled"),
                                         "nfe": generator.check_nfe(args.nfe)}, indent=2))


if __name__ == "__main__":
    main()
