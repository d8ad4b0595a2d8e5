"""Sequences: is an action missed, or done at another time than the data's? The read-outs judge
each action of a sequence in the window its label gives (the data's own timing); the pipeline
times the parts by its duration model (generate/durations.py). This prints, for the sequence
captions of a split, the pass rate in the label's windows, the pass rate in the windows of the
pipeline's own parts (each cut where the pipeline's blend between two parts is half done), and
how far apart the two sets of cuts lie.

    python bench/sequence_timing.py --data SYNTH [--split test] [--seeds 2] [--model DIR]
                                    [--shifts -0.3,-0.15,0,0.15]

--shifts: also generate with every cut moved by that many seconds (earlier when positive: the
first part gives the frames, the last takes them) and print the label-window pass rate of each,
to see how sensitive the read-outs are to the parts' timing. Pick a shift on the train split,
never on the test split.
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path
from typing import Any

import numpy as np

import mlct
import mlct.generate.pipeline as pipeline
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import passes
from mlct.generate.durations import split_frames


def own_windows(label: dict[str, Any], seams: tuple[int, ...], blend: int, fps: float,
                frames: int) -> tuple[dict[str, Any], list[float]]:
    """The label with each cut moved to the middle of the pipeline's blend between its parts
    (action_windows cuts halfway between one action's end and the next one's start), and how
    far each cut moved, in seconds (positive: the pipeline's is later)."""
    own = copy.deepcopy(label)
    scale = frames / label["frames"] if label.get("frames") else 1.0
    moved = []
    for i, seam in enumerate(seams):
        cut = (seam + blend / 2) / fps / scale
        before, after = own["actions"][i], own["actions"][i + 1]
        moved.append(cut - 0.5 * (float(before["end"]) + float(after["start"])))
        before["end"] = after["start"] = cut
    return own, moved


def shifted_split(frames_early: int):
    """split_frames with every cut `frames_early` frames earlier (negative: later)."""
    def split(weights: Any, frames: int, min_frames: int) -> list[int]:
        share = split_frames(weights, frames, min_frames)
        if len(share) > 1 and frames_early:
            move = int(np.clip(frames_early, -(share[-1] - min_frames), share[0] - min_frames))
            share[0] -= move
            share[-1] += move
        return share
    return split


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--shifts", default="", help="seconds, comma-separated")
    args = parser.parse_args()
    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    names = [n for n in layout.read_split(args.split) if n in labels
             and len(labels[n]["actions"]) > 1 and not labels[n].get("concurrent")][:args.limit]
    gen = mlct.load(args.model, backend="torch")
    captions = [layout.read_texts(n)[0].caption for n in names]
    lengths = [min(len(layout.load_features(n)), gen.max_frames) for n in names]
    fps = gen.skeleton.fps
    in_label = in_own = chained = 0
    moved: list[float] = []
    for seed in range(args.seeds):
        for name, motion, frames in zip(names, gen.generate(captions, lengths=lengths,
                                                            seed=seed * 100_000), lengths):
            label = labels[name]
            in_label += passes(motion.joints, label)
            seams = getattr(motion, "seams", ())
            if len(seams) != len(label["actions"]) - 1:  # made whole: its own windows unknown
                in_own += passes(motion.joints, label)
                continue
            chained += 1
            own, shift = own_windows(label, seams, motion.blend, fps, frames)
            moved += shift
            in_own += passes(motion.joints, own)
    total = len(names) * args.seeds
    print(f"{args.split}: {len(names)} sequence captions x {args.seeds} seeds "
          f"({chained} made as chained parts)")
    print(f"  pass in the label's windows:         {in_label}/{total} = {in_label / total:.3f}")
    print(f"  pass in the pipeline's own windows:  {in_own}/{total} = {in_own / total:.3f}")
    if moved:
        ms = np.asarray(moved)
        print(f"  the pipeline's cuts against the label's: mean {ms.mean():+.2f} s, mean |.| "
              f"{np.abs(ms).mean():.2f} s, median |.| {np.median(np.abs(ms)):.2f} s, 90th "
              f"percentile |.| {np.percentile(np.abs(ms), 90):.2f} s")
    for shift in [float(s) for s in args.shifts.split(",") if s.strip()]:
        pipeline.split_frames = shifted_split(int(round(shift * fps)))
        try:
            ok = sum(passes(m.joints, labels[n])
                     for seed in range(args.seeds)
                     for n, m in zip(names, gen.generate(captions, lengths=lengths,
                                                         seed=seed * 100_000)))
        finally:
            pipeline.split_frames = split_frames
        when = f"{abs(shift):.2f} s {'earlier' if shift > 0 else 'later'}"
        print(f"  every cut {when}: label windows {ok}/{total} = {ok / total:.3f}")


if __name__ == "__main__":
    main()
