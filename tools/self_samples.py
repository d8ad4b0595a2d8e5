"""A copy of a labelled dataset with the model's own passing samples added to its train split.

    python tools/self_samples.py --data SRC --model MODEL_DIR --out DST [--samples 8]

For each one-action training motion of SRC (labels.jsonl), the model samples `--samples`
latents from its first caption at the motion's length; the first candidate whose read-outs
(mlct.eval.readouts, the benchmark's checks) all pass is added to DST as a motion of its own,
with the original motion's captions and label, and listed in DST's train split. The rest of
SRC is hard-linked (its list files and labels copied), so SRC is never written. Stage 2
fine-tuned on DST sees, beside the data, latents it produced itself that do what their
captions say (rejection-sampling fine-tuning; docs/training.md, "Fine-tuning on its own passing
samples").
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
from pathlib import Path

import numpy as np

import mlct
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import evaluate_label
from mlct.train.critic_samples import judged_candidates, one_action_names

LISTS = ("train.txt", "labels.jsonl")  # written in DST: copied, never linked


def copy_linked(src: Path, dst: Path) -> None:
    """dst as hard links to src's files, but the files this tool appends to are copies."""
    if dst.exists():
        raise SystemExit(f"{dst} exists; give a new directory")
    shutil.copytree(src, dst, copy_function=os.link)
    for name in LISTS:
        (dst / name).unlink()
        shutil.copy2(src / name, dst / name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--seed", type=int, default=7_000_003, help="the first candidate's seed")
    args = parser.parse_args()
    copy_linked(args.data, args.out)
    layout = DatasetLayout.existing(args.out)
    labels = read_labels(args.out)
    single = one_action_names(sorted(set(layout.read_split("train"))), labels)
    gen = mlct.load(args.model, backend="torch")
    added, rows = [], []
    for judged in judged_candidates(gen, layout, single, labels, args.samples, args.seed,
                                    gen.max_frames, evaluate_label):
        if not judged.passed.any():
            continue
        k = int(judged.passed.nonzero()[0])  # the first candidate that passes
        new = f"s{judged.name}_{k}"
        np.save(layout.features_path(new), judged.features[k].astype(np.float32))
        np.save(layout.joints_path(new), judged.joints[k].astype(np.float32))
        shutil.copy(layout.text_path(judged.name), layout.text_path(new))
        added.append(new)
        rows.append(dict(labels[judged.name], name=new))
    with open(args.out / "train.txt", "a", encoding="utf-8") as handle:
        handle.write("".join(f"{n}\n" for n in added))
    with open(args.out / "labels.jsonl", "a", encoding="utf-8") as handle:
        handle.write("".join(json.dumps(r) + "\n" for r in rows))
    print(f"{args.out}: {len(added)} of {len(single)} one-action training motions have a passing "
          f"sample among {args.samples}; added to the train split")


if __name__ == "__main__":
    main()
