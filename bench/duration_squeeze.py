"""A clip shorter than its parts' predicted durations: squeeze every part alike, or take the time
from the longest part first (generate/durations.py: squeeze_longest_first)? Where the data can
say: on the benchmark's sequence captions, how far the pipeline's cuts land from the data's
cuts under each rule, over all sequences and over those whose clip is shorter than the parts'
predicted shares, and over those shorter than 1/1.15 of them (past the data's fastest
tempo, where the rules differ). The cuts are placed as `cut_errors` places them for
`mlct train durations` (train/durations.py); no motion is generated.

    python bench/duration_squeeze.py --data SYNTH [--model DIR] [--splits train,test]
"""

from __future__ import annotations

import argparse
from unittest import mock

import numpy as np

import mlct
import mlct.generate.durations as durations
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.generate.compose import split_actions
from mlct.generate.pipeline import MIN_PART_SECONDS
from mlct.train.durations import cut_errors, memoized_embedder, sequence_examples


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True)
    parser.add_argument("--model", default=None, help="model folder (default: the bundled one)")
    parser.add_argument("--splits", default="train,test")
    args = parser.parse_args(argv)
    generator = mlct.load(args.model, backend="torch")
    model = generator.durations
    if model is None or not model.offsets:
        raise SystemExit("duration_squeeze: the model has no version-2 duration model")
    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    fps = generator.skeleton.fps
    embed = memoized_embedder(generator)

    print(f"model {args.model or 'bundled'}; cut error = |pipeline's cut - data's cut| (s), "
          f"min part {MIN_PART_SECONDS} s")
    print(f"{'split':6} {'sequences':>22} {'n':>5} {'alike mean/p90':>16} "
          f"{'now mean/p90':>24}")
    for split in args.splits.split(","):
        names = set(layout.read_split(split))
        examples = sequence_examples({k: v for k, v in labels.items() if k in names},
                                     split_actions)
        wanted = [model.part_seconds(embed(e.parts)).sum() for e in examples]
        short = [e for e, w in zip(examples, wanted) if e.total < w]
        past = [e for e, w in zip(examples, wanted)
                if e.total < durations.FASTEST_TEMPO_SHARE * w]
        for title, chosen in (("all", examples), ("clip shorter than parts", short),
                              ("past the data's tempi", past)):
            if not chosen:
                print(f"{split:6} {title:>22} {0:5d}")
                continue
            row = []
            # the rule before: never past the data's tempi, so every part squeezed alike
            for share in (0.0, durations.FASTEST_TEMPO_SHARE):
                with mock.patch.object(durations, "FASTEST_TEMPO_SHARE", share):
                    errors = np.abs(cut_errors(model, chosen, embed, fps, MIN_PART_SECONDS))
                row.append(f"{errors.mean():.3f} / {np.percentile(errors, 90):.3f}")
            print(f"{split:6} {title:>22} {len(chosen):5d} {row[0]:>16} {row[1]:>24}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
