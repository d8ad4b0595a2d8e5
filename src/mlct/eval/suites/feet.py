"""Do planted feet stand still? The pipeline's foot lock (motion/foot_lock.py) off and on.

    python bench/quality.py feet --data SYNTH [--model DIR] [--seeds 2] [--limit N] [--json OUT]

The test captions of a procedural benchmark at their real lengths, --seeds seeds, made twice
with the same seeds: the joints as decoded (generator.foot_lock = None) and planted (the
default). Per family, and for the ground-truth motions as the data has them:
  slide      mean toe speed over the contact spans (the toe under 5 cm and slower than
             0.8 m/s, at least 3 frames: foot_lock.contact_spans, here also the spans that
             stray too far to be held, which the lock leaves as they are), m/s: 0 when a
             standing foot stands;
  skate      GMD's foot-skating ratio (motion/physics.py: toe under 5 cm moving faster than
             0.5 m/s), which also counts the fast frames as a toe lands and leaves, which the
             lock leaves alone;
  pass       the read-out checks of the label (eval/readouts.py): the lock must not cost any;
  knee       the largest knee move the lock made, m;
  smooth     the legs' (knees, ankles, feet) mean jerk, m/s^3, and the 99th percentile of their
             acceleration, m/s^2, over all motions: a hold that popped in or out would raise
             them.
Also the lock's time per motion.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

import mlct
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import evaluate_label
from mlct.motion.features import features_to_joints
from mlct.motion.foot_lock import FootLock, contact_slide, lock_feet
from mlct.motion.physics import foot_skating_ratio
from mlct.motion.skeleton import HUMANML3D

MAX_FRAMES = 196


def leg_smoothness(joints: np.ndarray) -> tuple[float, float]:
    """(mean |jerk| m/s^3, 99th-percentile acceleration m/s^2) of the knees, ankles and feet."""
    legs = [j for ankle, toe in (HUMANML3D.foot_left, HUMANML3D.foot_right)
            for j in (HUMANML3D.parents[ankle], ankle, toe)]
    fps = HUMANML3D.fps
    jerk = float(np.abs(np.diff(joints[:, legs], 3, axis=0)).mean() * fps**3)
    accel = np.linalg.norm(np.diff(joints[:, legs], 2, axis=0), axis=-1) * fps**2
    return jerk, float(np.percentile(accel, 99))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--json", type=Path, default=None)


def run(args: argparse.Namespace) -> None:

    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    names = [n for n in layout.read_split("test") if n in labels][: args.limit]
    real = [features_to_joints(layout.load_features(n)[:MAX_FRAMES]) for n in names]
    captions = [layout.read_texts(n)[0].caption for n in names]
    lengths = [len(r) for r in real]
    families = [labels[n]["actions"][0]["family"] if len(labels[n]["actions"]) == 1
                else "sequence" for n in names]
    pipe = mlct.load(args.model)

    rows: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))

    def add(column: str, family: str, joints: np.ndarray, label: dict) -> None:
        for key in (family, "ALL"):
            row = rows[key]
            row[f"{column} slide"].append(contact_slide(joints, HUMANML3D))
            row[f"{column} skate"].append(foot_skating_ratio(joints, HUMANML3D))
            row[f"{column} pass"].append(all(ok for _, ok in evaluate_label(joints, label)))

    for name, family, joints in zip(names, families, real):
        add("truth", family, joints, labels[name])
    lock_seconds, knee_moves = [], []
    smooth: dict[str, list[tuple[float, float]]] = {
        "truth": [leg_smoothness(j) for j in real], "decoded": [], "planted": []}
    knees = [HUMANML3D.parents[HUMANML3D.foot_left[0]], HUMANML3D.parents[HUMANML3D.foot_right[0]]]
    for seed in range(args.seeds):
        made = {}
        for column, lock in (("decoded", None), ("planted", FootLock())):
            pipe.foot_lock = lock
            made[column] = pipe.generate(captions, lengths=lengths, seed=seed * 100_000)
        for name, family, off, on in zip(names, families, made["decoded"], made["planted"]):
            add("decoded", family, off.joints, labels[name])
            add("planted", family, on.joints, labels[name])
            smooth["decoded"].append(leg_smoothness(off.joints))
            smooth["planted"].append(leg_smoothness(on.joints))
            start = time.perf_counter()
            lock_feet(off.joints, HUMANML3D)
            lock_seconds.append(time.perf_counter() - start)
            knee_moves.append(float(np.abs(on.joints[:, knees] - off.joints[:, knees]).max()))
    pipe.foot_lock = FootLock()

    columns = ("truth", "decoded", "planted")
    print(f"{len(names)} test motions of {args.data}, {args.seeds} seeds; model "
          f"{args.model or 'bundled'}")
    print(f"{'family':14}" + "".join(f"{c + ' ' + m:>16}" for m in ("slide", "skate", "pass")
                                      for c in columns))
    summary = {}
    for family in sorted(rows, key=lambda f: (f == "ALL", f)):
        row = rows[family]
        means = {f"{c} {m}": float(np.mean(row[f"{c} {m}"])) for m in ("slide", "skate", "pass")
                 for c in columns}
        summary[family] = means
        print(f"{family:14}" + "".join(f"{means[f'{c} {m}']:16.3f}"
                                       for m in ("slide", "skate", "pass") for c in columns))
    print(f"lock time per motion: median {np.median(lock_seconds) * 1000:.2f} ms, max "
          f"{np.max(lock_seconds) * 1000:.2f} ms; largest knee move {np.max(knee_moves):.3f} m, "
          f"median {np.median(knee_moves):.3f} m")
    print("legs' smoothness (mean jerk m/s^3, acceleration p99 m/s^2): " + "; ".join(
        f"{c} {np.mean([a for a, _ in v]):.1f}, {np.mean([b for _, b in v]):.1f}"
        for c, v in smooth.items()))
    if args.json is not None:
        args.json.write_text(json.dumps({"families": summary, "lock_ms_median":
                                         float(np.median(lock_seconds) * 1000)}, indent=1))
