"""Controlled generation on held-out benchmark motions: control error, text read-outs, foot
skating, time, for each way of meeting the controls.

    python -m mlct.cli data synth --out /tmp/synth --num 400 --seed 0 --workers 1
    python bench/control.py --data /tmp/synth [--limit N] [--nfe 5] [--json OUT]
    MLCT_BACKEND=torch python bench/control.py --guidance [--models bundled DIR ...] [--seeds 30]
    python bench/control.py --speeds [--real DATASET] [--synth DATASET]
        [--methods paced-before paced steer candidates guide] [--seeds 5] [--json OUT]

Each test motion of the benchmark gives its own controls and its first caption the text:
- path: its root's (x, z) at every second and at its last frame (the path it really walks);
- keys: its full pose at a third and two thirds of its length;
- edit: its lower body kept, the upper body made anew from its caption.
Methods: none (plain generation, same seeds), paced (the default: a path walked by the text's
own motion re-timed to it, then the correction; keyframes by the best of 4), guide (decoder
guidance only), project (motion-space correction only), both (guidance then correction), best4
and best8 (candidates then correction), steer (projection inside the consistency steps, then
the correction). Reported: path error at the waypoints (mean, max, cm), keyframe joint error
(mean, cm), the read-out pass rate of the quality suites' checks (its Tally, on the same
labels), the GMD foot-skating ratio (the data's in the last row), and ms per motion at batch 1
(the ratio to plain generation).

--guidance: how far decoder guidance alone brings a walk toward a path, the measure of
tests/test_control.py over more seeds and several models side by side. For each seed, "a person
walks forward" (120 frames) is made with guidance and without (no projection, one candidate,
the same seed), and the mean distance of the root from the path's waypoints with guidance is
divided by that without. Printed per model: the mean, median and standard error of that ratio
(1: guidance did nothing; one seed's ranges from about 0.2 to 1.6, so compare on 30 seeds).
Guidance needs the torch backend (its gradients run through the torch decoder).

--speeds: paths asking for another pace than the text's, and curves. The text's own speed is
measured on plain generations ("a person walks forward", "a person jogs forward", 6 s, the
root's start-to-end distance over the time); then straight paths along +Z at 0.5, 1, 1.5 and 2
times it, and an arc (a quarter circle) and an S (a 0.5 m sine) at 1 times it, waypoints every
second and at the last frame. Per row, over --seeds seeds: the root's distance from the
waypoints before the final correction (mean, max, cm) and after it (max), the GMD foot-skating
ratio, the cadence (steps per second: the lower foot's changes of side) and its stride (m per
step), and ms per motion at batch 1 against plain generation's; each method's table, then the
methods side by side (default: paced-before, the default method as it was; paced, as it is:
a source short of the path made again, its time-warp smoothed over 0.75 frames; steer, the
projection inside the consistency steps, control/steered.py; candidates and guide on request,
guide on the torch backend). --real
DATASET adds the skating ratio of its walks (provenance labels that name a walk), the figure a
walk is held to; --synth DATASET that of a procedural benchmark's one-action walks and jogs
(the figure for a jog, which the real sets lack).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

import mlct
from mlct.data.layout import DatasetLayout, provenance_label, read_provenance
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import evaluate_label
from mlct.eval.suites.common import MAX_FRAMES, Tally  # the read-outs' tally
from mlct.generate.control.schema import Control, Keyframe, control_from_dict, part_joints
from mlct.generate.control.pace import Pacing
from mlct.generate.control.controlled import (ControlMethod, controlled_motion,
                                              generate_controlled)
from mlct.motion.features import features_to_joints
from mlct.motion.gait import steps_per_second
from mlct.motion.physics import foot_skating_ratio

METHODS = {"paced": ControlMethod(),
           "guide": ControlMethod(pace=False, guide=True, project=False, candidates=1),
           "project": ControlMethod(pace=False, guide=False, candidates=1),
           "both": ControlMethod(pace=False, guide=True, candidates=1),
           "best4": ControlMethod(pace=False, guide=False, candidates=4),
           "best8": ControlMethod(pace=False, guide=False, candidates=8),
           "steer": ControlMethod(pace=False, steer=True)}


def path_control(joints: np.ndarray) -> tuple[Control, np.ndarray]:
    frames = np.unique(np.r_[np.arange(0, len(joints), 20), len(joints) - 1])
    return Control(path=joints[frames, 0][:, [0, 2]], path_frames=frames), frames


def key_control(joints: np.ndarray) -> tuple[Control, list[int]]:
    frames = [len(joints) // 3, 2 * len(joints) // 3]
    return Control(keyframes=tuple(Keyframe(f, {j: tuple(p) for j, p in enumerate(joints[f])})
                                   for f in frames)), frames


def acceleration(joints: np.ndarray, fps: float) -> float:
    """Mean joint acceleration (m/s^2): corrections that add kinks or jitter raise it."""
    return float(np.linalg.norm(np.diff(joints, n=2, axis=0), axis=-1).mean() * fps ** 2)


def record(st: dict[str, list], label: dict[str, Any], made: np.ndarray, seconds: float,
           skel: Any) -> None:
    st["tally"][0].add(label, evaluate_label(made, label))
    st["skate"].append(foot_skating_ratio(made, skel))
    st["acc"].append(acceleration(made, skel.fps))
    st["ms"].append(seconds)


GUIDE_PATH = [[0.0, 0.0, 0], [0.2, 1.2, 40], [0.9, 2.2, 80], [1.9, 2.6, 119]]  # the test's path
GUIDE_FRAMES = 120


def guidance_ratios(pipe: Any, seeds: int) -> np.ndarray:
    control = control_from_dict({"path": GUIDE_PATH}, pipe.skeleton).check(GUIDE_FRAMES,
                                                                          pipe.skeleton)
    frames, target = [p[2] for p in GUIDE_PATH], np.array(GUIDE_PATH)[:, :2]

    def error(guide: bool, seed: int) -> float:
        made = generate_controlled(pipe, "a person walks forward", GUIDE_FRAMES, control, None,
                                   seed,
                                   ControlMethod(pace=False, guide=guide, project=False,
                                                 candidates=1))
        return float(np.linalg.norm(made.joints[frames, 0][:, [0, 2]] - target, axis=1).mean())
    return np.array([error(True, s) / error(False, s) for s in range(seeds)])


def guidance_main(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    if os.environ.get("MLCT_BACKEND", "auto") != "torch":
        parser.error("run with MLCT_BACKEND=torch: guidance needs the torch backend")
    print(f"guided / plain path error, {args.seeds} seeds (seed 0 first)")
    print(f"{'model':40} {'mean':>6} {'median':>7} {'s.e.':>6} {'first 6':>8}")
    for name in args.models:
        r = guidance_ratios(mlct.load(None if name == "bundled" else Path(name)), args.seeds)
        print(f"{name:40} {r.mean():6.3f} {np.median(r):7.3f} "
              f"{r.std() / np.sqrt(len(r)):6.3f} {r[:6].mean():8.3f}", flush=True)


# ---------------------------------------------------------------- --speeds: pace and curves

SPEED_PROMPTS = {"walk": "a person walks forward", "jog": "a person jogs forward"}
SPEED_FRAMES = 120  # 6 s at 20 fps
SPEED_FACTORS = (0.5, 1.0, 1.5, 2.0)
SPEED_METHODS = {
    "paced": ControlMethod(),  # the default: the text's motion re-timed and laid along the path
    # the same as it was: a source 3 % short of the path kept, its time-warp smoothed over 1 frame
    "paced-before": ControlMethod(pacing=Pacing(covers=0.97, smoothing=1.0)),
    "steer": ControlMethod(pace=False, steer=True),  # projection inside the consistency steps
    "candidates": ControlMethod(pace=False),  # best of 4, then the correction
    "guide": ControlMethod(pace=False, guide=True, candidates=1)}  # torch backend
DEFAULT_SPEED_METHODS = ("paced-before", "paced", "steer")
SKATING_FAMILIES = ("walk", "jog")  # the benchmark's own motions a controlled one is held to


def waypoint_frames(frames: int, fps: float) -> np.ndarray:
    """A waypoint every second and at the last frame."""
    return np.unique(np.r_[np.arange(0, frames, int(fps)), frames - 1])


def straight_path(speed: float, frames: int, fps: float) -> Control:
    """Along +Z from the origin at `speed` m/s."""
    at = waypoint_frames(frames, fps)
    return Control(path=np.stack([np.zeros(len(at)), speed * at / fps], axis=1), path_frames=at)


def curved_path(kind: str, speed: float, frames: int, fps: float) -> Control:
    """An arc (a quarter circle turning right) or an S (one period of a 0.5 m sine across),
    walked at `speed` m/s from the origin along +Z."""
    length = speed * (frames - 1) / fps
    s = np.linspace(0.0, 1.0, 801)
    if kind == "arc":
        radius = length / (np.pi / 2)
        line = np.stack([radius * (1 - np.cos(s * np.pi / 2)), radius * np.sin(s * np.pi / 2)], 1)
    elif kind == "S":
        line = np.stack([0.5 * np.sin(2 * np.pi * s), s * length], axis=1)
    else:
        raise ValueError(f"unknown curve {kind!r}")
    along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))]
    line, along = line * (length / along[-1]), along * (length / along[-1])  # `length` long
    at = waypoint_frames(frames, fps)
    gone = speed * at / fps
    return Control(path=np.stack([np.interp(gone, along, line[:, 0]),
                                  np.interp(gone, along, line[:, 1])], axis=1), path_frames=at)


def real_walk_skating(root: Path, skel: Any) -> tuple[float, int]:
    """The GMD skating ratio of a dataset's walks (provenance labels naming a walk), mean and
    count: the figure a controlled walk is held to."""
    layout = DatasetLayout.existing(root)
    names = [r["name"] for r in read_provenance(root) if "walk" in provenance_label(r)]
    if not names:
        raise SystemExit(f"{root}: no motion whose provenance label names a walk")
    return float(np.mean([foot_skating_ratio(layout.load_joints(n), skel) for n in names])), \
        len(names)


def synth_skating(root: Path, skel: Any) -> dict[str, tuple[float, int]]:
    """The GMD skating ratio of a procedural benchmark's one-action walks and jogs (its
    labels.jsonl), mean and count per family: the figure where no real capture has the gait."""
    labels = read_labels(root)
    layout = DatasetLayout.existing(root)
    out = {}
    for family in SKATING_FAMILIES:
        names = [n for n, r in labels.items()
                 if [a["family"] for a in r.get("actions", [])] == [family]]
        if names:
            out[family] = (float(np.mean([foot_skating_ratio(layout.load_joints(n), skel)
                                          for n in names])), len(names))
    return out


def speed_cases() -> list[tuple[str, str, float]]:
    """(gait, path kind, factor of the text's speed) of every --speeds row."""
    return [(k, "straight", f) for k in SPEED_PROMPTS for f in SPEED_FACTORS] \
        + [(k, c, 1.0) for k in SPEED_PROMPTS for c in ("arc", "S")]


def speed_row(pipe: Any, args: argparse.Namespace, method: ControlMethod, key: str,
              control: Control, speed: float) -> dict[str, float]:
    """One row of the --speeds table: `method` on `control` over the seeds, each timed next to
    a plain generation of the same seed (the machine's load alike)."""
    skel, frames = pipe.skeleton, SPEED_FRAMES
    before, after, ms, plain_ms = [], [], [], []
    for seed in range(args.seeds):
        start = time.perf_counter()
        pipe.generate(SPEED_PROMPTS[key], lengths=frames, nfe=args.nfe, seed=seed)
        plain_ms.append(time.perf_counter() - start)
        start = time.perf_counter()
        made = controlled_motion(pipe, SPEED_PROMPTS[key], frames, control, args.nfe, seed,
                                 method)
        ms.append(time.perf_counter() - start)
        before.append(made.before)
        after.append(made.motion.joints)
    errors = np.concatenate([np.linalg.norm(j[control.path_frames, 0][:, [0, 2]]
                                            - control.path, axis=1) for j in before])
    final = max(np.linalg.norm(j[control.path_frames, 0][:, [0, 2]] - control.path,
                               axis=1).max() for j in after)
    return {"speed": speed, "error_mean_cm": 100 * float(errors.mean()),
            "error_max_cm": 100 * float(errors.max()), "final_max_cm": 100 * float(final),
            "skating": float(np.mean([foot_skating_ratio(j, skel) for j in after])),
            "cadence": float(np.mean([steps_per_second(j, skel) for j in after])),
            "ms": 1e3 * float(np.median(ms)), "x_plain": float(np.median(ms) / np.median(plain_ms))}


def speeds_main(args: argparse.Namespace) -> None:
    pipe = mlct.load(args.model)
    skel, fps, frames = pipe.skeleton, pipe.skeleton.fps, SPEED_FRAMES
    pipe.encode_text(list(SPEED_PROMPTS.values()))
    pipe.generate(SPEED_PROMPTS["walk"], lengths=frames, seed=0)  # warm-up
    plain: dict[str, dict[str, float]] = {}
    for key, text in SPEED_PROMPTS.items():  # the text's own speed: plain generations
        made, ms = [], []
        for seed in range(args.seeds):
            start = time.perf_counter()
            made.append(pipe.generate(text, lengths=frames, nfe=args.nfe, seed=seed)[0].joints)
            ms.append(time.perf_counter() - start)
        plain[key] = {"speed": float(np.mean([np.linalg.norm(j[-1, 0, [0, 2]] - j[0, 0, [0, 2]])
                                              for j in made])) / ((frames - 1) / fps),
                      "skating": float(np.mean([foot_skating_ratio(j, skel) for j in made])),
                      "cadence": float(np.mean([steps_per_second(j, skel) for j in made])),
                      "ms": 1e3 * float(np.median(ms))}
    tables: dict[str, dict[str, dict[str, float]]] = {m: {} for m in args.methods}
    warm = straight_path(plain["walk"]["speed"], frames, fps).check(frames, skel)
    for name in args.methods:  # each method's first call (its imports, the encoder) untimed
        controlled_motion(pipe, SPEED_PROMPTS["walk"], frames, warm, args.nfe, 0,
                          SPEED_METHODS[name])
    for key, kind, factor in speed_cases():
        speed = factor * plain[key]["speed"]
        control = (straight_path(speed, frames, fps) if kind == "straight"
                   else curved_path(kind, speed, frames, fps)).check(frames, skel)
        for name in args.methods:  # the methods of a row one after the other: the same load
            tables[name][f"{key} {kind} {factor:g}x"] = speed_row(pipe, args, SPEED_METHODS[name],
                                                                  key, control, speed)
    real = real_walk_skating(args.real, skel) if args.real is not None else None
    synth = synth_skating(args.synth, skel) if args.synth is not None else {}

    print(f"{args.seeds} seeds, {frames} frames, nfe {pipe.check_nfe(args.nfe)}, batch 1, backend "
          f"{pipe.backend}; waypoints every second and at the last frame")
    for key, p in plain.items():
        print(f"plain {key} ({SPEED_PROMPTS[key]!r}): {p['speed']:.2f} m/s, skating "
              f"{p['skating']:.3f}, {p['cadence']:.2f} steps/s, "
              f"{p['speed'] / max(p['cadence'], 1e-9):.2f} m/step, {p['ms']:.0f} ms")
    for name, rows in tables.items():
        print(f"\nmethod {name}")
        print(f"{'path':<18}{'m/s':>6}{'err mean':>9}{'err max':>8}{'final':>7}{'skating':>8}"
              f"{'steps/s':>8}{'m/step':>7}{'ms':>7}{'x plain':>8}")
        for row, r in rows.items():
            print(f"{row:<18}{r['speed']:>6.2f}{r['error_mean_cm']:>9.1f}"
                  f"{r['error_max_cm']:>8.1f}{r['final_max_cm']:>7.1f}{r['skating']:>8.3f}"
                  f"{r['cadence']:>8.2f}{r['speed'] / max(r['cadence'], 1e-9):>7.2f}"
                  f"{r['ms']:>7.0f}{r['x_plain']:>8.2f}")
    if len(tables) > 1:  # side by side: error before the correction, skating, time
        print(f"\n{'path':<18}" + "".join(f"{name + ': err / max, skating, x':>34}"
                                          for name in tables))
        for row in next(iter(tables.values())):
            print(f"{row:<18}" + "".join(
                f"{t[row]['error_mean_cm']:>14.1f} /{t[row]['error_max_cm']:>6.1f}"
                f"{t[row]['skating']:>7.3f}{t[row]['x_plain']:>6.2f}" for t in tables.values()))
    if real is not None:
        print(f"real walks ({args.real}, {real[1]} motions): skating {real[0]:.3f}; within 20 %: "
              f"{0.8 * real[0]:.3f}-{1.2 * real[0]:.3f}")
    for family, (ratio, count) in synth.items():
        print(f"benchmark {family}s ({args.synth}, {count} one-action motions): skating "
              f"{ratio:.3f}; within 20 %: {0.8 * ratio:.3f}-{1.2 * ratio:.3f}")
    print("(err: the root's distance from the waypoints before the final correction, cm; final: "
          "after it; skating: GMD foot-skating ratio; steps/s: the lower foot's changes of side)")
    if args.json is not None:
        report = {"methods": list(args.methods), "seeds": args.seeds, "plain": plain,
                  "rows": tables, "real_walk_skating": None if real is None else real[0],
                  "synth_skating": {f: v[0] for f, v in synth.items()}}
        args.json.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=None, help="a procedural benchmark")
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--split", default="test")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--nfe", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--guidance", action="store_true",
                        help="guidance alone against plain sampling on a path (above)")
    parser.add_argument("--models", nargs="+", default=["bundled"], help="with --guidance")
    parser.add_argument("--seeds", type=int, default=None,
                        help="with --guidance (default 30) or --speeds (default 5)")
    parser.add_argument("--speeds", action="store_true",
                        help="paths at other paces than the text's, and curves (above)")
    parser.add_argument("--methods", nargs="+", choices=sorted(SPEED_METHODS),
                        default=list(DEFAULT_SPEED_METHODS),
                        help="with --speeds: the methods, side by side in one run")
    parser.add_argument("--real", type=Path, default=None,
                        help="with --speeds: a real dataset whose walks' skating is the figure")
    parser.add_argument("--synth", type=Path, default=None,
                        help="with --speeds: a procedural benchmark whose walks' and jogs' "
                             "skating is the figure (its labels.jsonl)")
    args = parser.parse_args()
    if args.guidance:
        args.seeds = 30 if args.seeds is None else args.seeds
        return guidance_main(args, parser)
    if args.speeds:
        args.seeds = 5 if args.seeds is None else args.seeds
        return speeds_main(args)
    if args.data is None:
        parser.error("--data is required (or --guidance, --speeds)")

    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    names = [n for n in layout.read_split(args.split) if n in labels][: args.limit]
    real = [features_to_joints(layout.load_features(n)[:MAX_FRAMES]) for n in names]
    captions = [layout.read_texts(n)[0].caption for n in names]
    pipe = mlct.load(args.model)
    skel = pipe.skeleton
    upper = part_joints("upper", skel)
    kept = [j for j in range(skel.n_joints) if j not in upper]
    pipe.encode_text(captions)  # every caption's embedding memoised: the times are sampling's
    pipe.generate(captions[0], lengths=len(real[0]), nfe=args.nfe, seed=0)  # warm-up
    generate_controlled(pipe, captions[0], len(real[0]), path_control(real[0])[0], args.nfe, 0)

    # Per motion, plain generation and every method in turn, so that the machine's load at
    # that moment weighs on all of them alike (the times are ratios).
    stats: dict[str, dict[str, list]] = {m: {"tally": [Tally()], "skate": [], "ms": [],
                                             "path": [], "key": [], "acc": []}
                                         for m in ("none", *METHODS)}
    for name, cap, joints in zip(names, captions, real):
        start = time.perf_counter()
        made = pipe.generate(cap, lengths=len(joints), nfe=args.nfe, seed=args.seed,
                             split_actions=False)[0].joints
        record(stats["none"], labels[name], made, time.perf_counter() - start, skel)
        for method_name, method in METHODS.items():
            for task in ("path", "keys"):
                control, frames = (path_control if task == "path" else key_control)(joints)
                start = time.perf_counter()
                made = generate_controlled(pipe, cap, len(joints), control, args.nfe, args.seed,
                                           method).joints
                record(stats[method_name], labels[name], made, time.perf_counter() - start, skel)
                if task == "path":
                    stats[method_name]["path"].append(np.linalg.norm(
                        made[frames, 0][:, [0, 2]] - joints[frames, 0][:, [0, 2]], axis=-1))
                else:
                    stats[method_name]["key"].append(
                        np.linalg.norm(made[frames] - joints[frames], axis=-1).mean())
    rows: dict[str, dict[str, Any]] = {}
    for method_name, st in stats.items():
        rows[method_name] = {"pass": st["tally"][0].summary()["overall"],
                             "skating": float(np.mean(st["skate"])),
                             "acc": float(np.mean(st["acc"])), "ms": 1e3 * float(np.mean(st["ms"]))}
        if st["path"]:
            errs = np.concatenate(st["path"])
            rows[method_name].update(path_mean_cm=100 * float(errs.mean()),
                                     path_max_cm=100 * float(errs.max()),
                                     key_cm=100 * float(np.mean(st["key"])))
    plain_ms = rows["none"]["ms"]
    # body-part edits: keep the lower body of each motion, make the upper body from its caption
    edit_err, edit_ms = [], []
    for cap, joints in zip(captions, real):
        control = Control(edit=joints, parts=upper)
        start = time.perf_counter()
        made = generate_controlled(pipe, cap, len(joints), control, args.nfe, args.seed).joints
        edit_ms.append(1e3 * (time.perf_counter() - start))
        edit_err.append(float(np.linalg.norm(made[:, kept] - joints[:, kept], axis=-1).max()))
    data_skate = float(np.mean([foot_skating_ratio(j, skel) for j in real]))
    data_acc = float(np.mean([acceleration(j, skel.fps) for j in real]))

    print(f"{len(names)} motions of {args.data} ({args.split}), nfe {pipe.check_nfe(args.nfe)}, "
          f"seed {args.seed}, batch 1; controls: own path (1 s waypoints), own poses at T/3 "
          f"and 2T/3")
    head = (f"{'method':<9}{'path mean':>10}{'path max':>10}{'key err':>9}{'pass':>7}"
            f"{'skating':>9}{'acc':>7}{'ms':>8}{'x plain':>9}")
    print(head)
    for method_name, r in rows.items():
        cells = [f"{r[k]:>9.1f}" if k in r else f"{'-':>9}" for k in
                 ("path_mean_cm", "path_max_cm", "key_cm")]
        print(f"{method_name:<9}{cells[0]:>10}{cells[1]:>10}{cells[2]:>9}{r['pass']:>7.3f}"
              f"{r['skating']:>9.3f}{r['acc']:>7.2f}{r['ms']:>8.1f}{r['ms'] / plain_ms:>9.2f}")
    print(f"{'data':<9}{'':>10}{'':>10}{'':>9}{'':>7}{data_skate:>9.3f}{data_acc:>7.2f}")
    print(f"edit (upper body anew, lower kept): untouched joints max error "
          f"{100 * max(edit_err):.4f} cm, {np.mean(edit_ms):.1f} ms")
    print("(errors in cm; pass: read-out pass rate; skating: GMD foot-skating ratio; acc: mean "
          "joint acceleration, m/s^2)")
    if args.json is not None:
        report = {"rows": rows, "data_skating": data_skate, "data_acc": data_acc,
                  "motions": len(names),
                  "edit_untouched_max_cm": 100 * max(edit_err)}
        args.json.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
