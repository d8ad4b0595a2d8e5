"""Real capture: the autoencoder's reconstructions of real held-out motions, the variety of a
model's motions for one label against the real data's, and foot skating against the data's.

    python bench/quality.py real --data REAL [--ae RUN_OR_MODEL] [--model MODEL] [--seeds 5]

REAL is a dataset imported with `mlct data import --corpus ...` (its provenance.jsonl names each
motion's label: a corpus content such as "wave-left-hand", or CMU's description), or a
procedural benchmark, whose one-action motions are grouped by their label.
- (0) always: the data's floor over all its motions: the floor tilt that can still be read
  under them (motion/floor.py; the import levels it) and how many of the walks read as in flight
  (the walk read-out "no_flight": both feet 2 cm off the floor in more than 3 frames);
- (a) with --ae: per label of the split, the reconstruction's mean joint distance (MPJPE, the
  root's path included) and the pose's alone (each frame's joints relative to its pelvis); and
  per label with at least --min-motions motions, the spread of the reconstructions against the
  data's (the distance of (b) below): the most variety any model on this decoder can draw;
  and the level walks of the split that read as in flight (both feet 2 cm, and 5 cm, up in more
  than 3 frames) in the data and in their reconstructions: a decoder that lifts the feet makes
  every model on it float;
- (b) with --model (or 'bundled'): for each label with at least --min-motions motions, one
  caption of it generated --seeds times at the label's median length; the variety is the mean
  joint distance between two seeds' motions (every pair, frame by frame over the shorter,
  both starting where the features put them: at the origin, facing +Z); the data's variety is
  the same distance between its motions of the label (all splits, at most 12 spread evenly over
  its takes in name order, so that every style is among them). Measured at the
  defaults, with one candidate (no critic), with the text anchors off and with the critic's
  best of N (margin 0), so that each pull towards one motion shows; then the defaults against
  the variety goal (VARIETY_RATIO of the data's spread, median over the labels, and every
  label's seeds VARIETY_DISTANCE apart), each part met or not. With --ae too, the same
  distance between the autoencoder's reconstructions of the data's motions: the most spread the model can draw for the label,
  since every motion it makes comes out of that decoder;
- (c) foot skating (GMD's ratio) of the defaults' motions against the data's for the same labels.
"""

from __future__ import annotations

import argparse
import itertools
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from mlct.data.labels import LABELS_FILE, read_labels
from mlct.data.layout import DatasetLayout, provenance_label, read_provenance
from mlct.eval.suites.common import set_critic_margin
from mlct.motion.features import features_to_joints
from mlct.motion.physics import foot_skating_ratio
from mlct.motion.skeleton import HUMANML3D

MAX_PER_LABEL = 12  # the data's motions of one label compared pairwise
# The model's window (config data.max_motion_length): a longer real take is compared, and
# put through the autoencoder, on its first frames only.
WINDOW = 196


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True, help="an imported real corpus")
    parser.add_argument("--ae", type=Path, default=None, help="run or model for (a)")
    parser.add_argument("--model", default=None, help="model folder or 'bundled' for (b), (c)")
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--min-motions", type=int, default=3)
    parser.add_argument("--labels", default=None, help="only these labels, separated by ';' (labels hold commas)")
    parser.add_argument("--critic-margin", type=float, default=None,
                        help="the defaults' critic margin (default: the model's)")
    parser.add_argument("--json", type=Path, default=None)


def motion_labels(root: Path) -> dict[str, str]:
    """motion name -> its label (corpus content, else CMU's description); for a procedural
    benchmark (no provenance.jsonl), its one-action motions' labels ("kick(count=1,leg=right)"),
    so that a family's spread is measured the same way."""
    records = read_provenance(root)
    if records or not (root / LABELS_FILE).is_file():
        return {r["name"]: provenance_label(r) for r in records}
    return {name: r["label"] for name, r in read_labels(root).items()
            if len(r["actions"]) == 1 and not r.get("concurrent")}


def pairwise_distance(motions: list[np.ndarray]) -> float:
    """Mean over pairs of the mean joint distance, frame by frame over the shorter motion (m)."""
    pairs = []
    for a, b in itertools.combinations(motions, 2):
        n = min(len(a), len(b))
        pairs.append(float(np.linalg.norm(a[:n] - b[:n], axis=-1).mean()))
    return float(np.mean(pairs)) if pairs else float("nan")


def reconstructions(layout: DatasetLayout, names: list[str], labels: dict[str, str],
                    ae: Any) -> dict[str, dict[str, float]]:
    """Per label: the reconstructions' MPJPE and pose error; under "walks_in_flight", the level
    walks among `names` that read as in flight (more than 3 frames with both feet above
    FLIGHT_CLEARANCES), in the data and in the reconstructions."""
    from mlct.eval.readouts import airborne_frames

    per: dict[str, list[tuple[float, float]]] = defaultdict(list)
    flying = {who: {f"{c * 100:g}cm": 0 for c in FLIGHT_CLEARANCES} for who in ("data", "made")}
    walks = 0
    for name in names:
        features = layout.load_features(name)[:WINDOW]
        truth, made = features_to_joints(features), features_to_joints(ae(features))
        pose = np.linalg.norm((truth - truth[:, :1]) - (made - made[:, :1]), axis=-1).mean()
        per[labels[name]].append((float(np.linalg.norm(truth - made, axis=-1).mean()), pose))
        if is_level_walk(labels[name]):
            walks += 1
            for who, joints in (("data", truth), ("made", made)):
                for c in FLIGHT_CLEARANCES:
                    flying[who][f"{c * 100:g}cm"] += airborne_frames(joints, c) > 3
    out: dict[str, Any] = {label: {"n": len(v), "mpjpe_m": float(np.mean([m for m, _ in v])),
                                   "pose_m": float(np.mean([p for _, p in v]))}
                           for label, v in per.items()}
    return out | {"walks_in_flight": {"walks": walks, **flying}}


def run(args: argparse.Namespace) -> None:
    layout = DatasetLayout.existing(args.data)
    labels = motion_labels(args.data)
    report: dict[str, Any] = {"data": str(args.data)}
    report["floor"] = floor_report(layout, labels)
    ae = args.load_autoencoder(args.ae) if args.ae is not None else None
    if ae is not None:
        names = [n for n in layout.read_split(args.split) if n in labels]
        recon = reconstructions(layout, names, labels, ae)
        flight = recon.pop("walks_in_flight")
        report["reconstruction"], report["reconstruction_walks_in_flight"] = recon, flight
        allv = [(r["mpjpe_m"], r["pose_m"], r["n"]) for r in recon.values()]
        n = sum(c for _, _, c in allv)
        print(f"(a) {args.ae}: {n} {args.split} motions of {args.data}: MPJPE "
              f"{sum(m * c for m, _, c in allv) / n * 100:.1f} cm, pose "
              f"{sum(p * c for _, p, c in allv) / n * 100:.1f} cm")
        for label, r in sorted(recon.items()):
            print(f"    {label:32s} n={r['n']:3d}  MPJPE {r['mpjpe_m'] * 100:5.1f} cm  "
                  f"pose {r['pose_m'] * 100:5.1f} cm")
        print(f"    level walks read as in flight, data -> reconstructions (of {flight['walks']}): "
              + ", ".join(f"{k} up {flight['data'][k]} -> {flight['made'][k]}"
                          for k in flight["data"]))
        report["reconstruction_spread"] = reconstruction_spread(layout, labels, ae, args)
    if args.model is not None:
        report["variety"] = _variety(args, layout, labels, report.get("reconstruction_spread"))
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


# both feet this high (m) in more than 3 frames: 2 cm is the walk read-out's no_flight,
# 5 cm a clear float
FLIGHT_CLEARANCES = (0.02, 0.05)


def is_level_walk(label: str) -> bool:
    """A walk on a level floor, whose feet never both leave it (uneven or bumpy ground lifts
    them for real)."""
    label = label.lower()
    return "walk" in label and not any(w in label for w in ("uneven", "bump"))


def floor_report(layout: DatasetLayout, labels: dict[str, str]) -> dict[str, Any]:
    """(0): the tilt still under the motions and the walks that read as in flight."""
    from mlct.eval.readouts import flight_frames
    from mlct.motion.floor import floor_gradient

    tilts, walks, flying = [], 0, 0
    for name in sorted(labels):
        joints = layout.load_joints(name)
        gradient = floor_gradient(joints, HUMANML3D)
        if gradient is not None:
            tilts.append(float(np.degrees(np.arctan(np.linalg.norm(gradient)))))
        if is_level_walk(labels[name]):
            walks += 1
            flying += flight_frames(joints) > 3
    report = {"motions": len(labels), "tilt_read": len(tilts),
              "tilt_median_deg": float(np.median(tilts)) if tilts else None,
              "tilt_max_deg": max(tilts) if tilts else None, "walks": walks,
              "walks_in_flight": flying}
    tilt = (f"median {report['tilt_median_deg']:.2f} deg, max {report['tilt_max_deg']:.2f}"
            if tilts else "-")
    print(f"(0) floor of {len(labels)} motions: tilt readable under {len(tilts)}, {tilt}; "
          f"walks read as in flight (both feet 2 cm up in over 3 frames): {flying} of {walks}")
    return report


def spread_sets(labels: dict[str, str], args: argparse.Namespace) -> dict[str, list[str]]:
    """label -> the motions its spread is measured on: labels with at least --min-motions
    motions (only --labels where given), at most MAX_PER_LABEL each, spread evenly over its
    takes in name order, so that every style is among them."""
    by_label: dict[str, list[str]] = defaultdict(list)
    for name in sorted(labels):
        by_label[labels[name]].append(name)
    chosen = sorted(l for l, n in by_label.items() if len(n) >= args.min_motions)
    if args.labels:
        chosen = [l for l in chosen if l in args.labels.split(";")]
    out = {}
    for label in chosen:
        every = by_label[label]  # sorted by name: takes of one style sit together
        picks = np.linspace(0, len(every) - 1, min(len(every), MAX_PER_LABEL)).astype(int)
        out[label] = [every[i] for i in picks]
    return out


def reconstruction_spread(layout: DatasetLayout, labels: dict[str, str], ae: Any,
                          args: argparse.Namespace) -> dict[str, dict[str, float]]:
    """Per label: the data's spread, the reconstructions' and their ratio (printed)."""
    rows = {}
    for label, names in spread_sets(labels, args).items():
        features = [layout.load_features(n)[:WINDOW] for n in names]
        data = pairwise_distance([features_to_joints(f) for f in features])
        made = pairwise_distance([features_to_joints(ae(f)) for f in features])
        rows[label] = {"n": len(names), "data_m": data, "ae_m": made, "ratio": made / data}
    if rows:
        print("    the reconstructions' spread against the data's (cm; ratio):")
        for label, r in rows.items():
            print(f"    {label:32s} n={r['n']:3d}  data {r['data_m'] * 100:5.1f}  "
                  f"AE {r['ae_m'] * 100:5.1f}  {r['ratio']:5.2f}")
        print(f"    median ratio {np.median([r['ratio'] for r in rows.values()]):.2f} over "
              f"{len(rows)} labels")
    return rows


def _variety(args: argparse.Namespace, layout: DatasetLayout, labels: dict[str, str],
             ceiling: dict[str, dict[str, float]] | None = None) -> dict[str, Any]:
    """ceiling: reconstruction_spread's rows, shown beside the seeds' (its AE column)."""
    import mlct

    pipe = mlct.load(None if args.model == "bundled" else args.model)
    set_critic_margin(pipe, args.critic_margin)
    margin_default = pipe.critic.margin if pipe.critic is not None else None
    # (name, generate()'s options, text anchors on, critic margin); the best of N needs a critic
    settings = [("defaults", {}, True, margin_default),
                ("one_candidate", {"candidates": 1}, True, margin_default),
                ("no_anchors", {}, False, margin_default)]
    if pipe.critic is not None:
        settings.append(("best_of_n", {}, True, 0.0))
    rows: dict[str, Any] = {}
    anchors = pipe.text_anchors
    for label, names in spread_sets(labels, args).items():
        real = [features_to_joints(layout.load_features(n)[:WINDOW]) for n in names]
        seconds = float(np.median([len(j) for j in real])) / HUMANML3D.fps
        caption = layout.read_texts(names[0])[0].caption
        row = {"caption": caption, "seconds": seconds, "data_m": pairwise_distance(real),
               "data_skating": float(np.mean([foot_skating_ratio(j, HUMANML3D) for j in real]))}
        if ceiling is not None:
            row["ae_m"] = ceiling[label]["ae_m"]
        for setting, kwargs, with_anchors, margin in settings:
            pipe.text_anchors = anchors if with_anchors else None
            if pipe.critic is not None:
                pipe.critic.margin = margin
            made = pipe.generate([caption] * args.seeds, seconds=seconds, seed=0, **kwargs)
            joints = [m.joints for m in made]
            row[f"{setting}_m"] = pairwise_distance(joints)
            if setting == "defaults":
                row["skating"] = float(np.mean([foot_skating_ratio(j, HUMANML3D)
                                                for j in joints]))
        pipe.text_anchors = anchors
        if pipe.critic is not None:
            pipe.critic.margin = margin_default
        rows[label] = row
    print(f"(b) variety of {args.seeds} seeds (mean joint distance between seeds, cm) against "
          f"the data's own for the label; (c) foot skating; model {args.model}")
    print(f"    critic margin at the defaults: {margin_default}; 'best': the best of N (margin 0)")
    print(f"    {'label':26s} {'data':>6s} {'default':>8s} {'ratio':>6s} {'1 cand':>7s} "
          f"{'no anch':>8s} {'best':>6s} {'skate':>6s} {'data sk':>7s} {'AE':>5s}")
    for label, r in rows.items():
        print(f"    {label:26s} {r['data_m'] * 100:6.1f} {r['defaults_m'] * 100:8.1f} "
              f"{r['defaults_m'] / r['data_m']:6.2f} {r['one_candidate_m'] * 100:7.1f} "
              f"{r['no_anchors_m'] * 100:8.1f} {r.get('best_of_n_m', float('nan')) * 100:6.1f} "
              f"{r['skating']:6.3f} {r['data_skating']:7.3f} "
              f"{r.get('ae_m', float('nan')) * 100:5.1f}")
    if rows:
        for setting, *_ in settings:
            ratios = [r[f"{setting}_m"] / r["data_m"] for r in rows.values()]
            print(f"    {setting:13s} median ratio {np.median(ratios):.2f} over {len(rows)} "
                  f"labels; at least {VARIETY_DISTANCE * 100:g} cm in "
                  f"{sum(r[f'{setting}_m'] >= VARIETY_DISTANCE for r in rows.values())}")
        print("    " + variety_verdict(rows))
    return rows


# The variety goal: at the defaults the seeds of one label spread at least this share of the
# data's own spread for it (median over the labels), and at least this far apart (m) on every
# label.
VARIETY_RATIO, VARIETY_DISTANCE = 0.8, 0.05


def variety_verdict(rows: dict[str, dict[str, float]]) -> str:
    """One line: the defaults against the variety goal, and whether each part is met."""
    ratio = float(np.median([r["defaults_m"] / r["data_m"] for r in rows.values()]))
    far = sum(r["defaults_m"] >= VARIETY_DISTANCE for r in rows.values())
    ratio_met = "met" if ratio >= VARIETY_RATIO else "not met"
    far_met = "met" if far == len(rows) else "not met"
    return (f"goal: median ratio >= {VARIETY_RATIO} ({ratio:.2f}: {ratio_met}); every label's "
            f"seeds >= {VARIETY_DISTANCE * 100:g} cm apart ({far} of {len(rows)}: {far_met})")
