"""Locomotion asked for longer than the data's clips: does it keep going, and how well?

    python bench/quality.py keep-going [--model MODEL_DIR] [--seeds 5] [--seconds 7 9.5]

For locomotion prompts (and, as controls, prompts whose motion should end: jumps, a wave, a
counted walk, a sit, spins and turns on the spot) at lengths past their natural one, each
generated twice with the same seed, the generator's keep-going off (as before
generate/compose/keep_going.py) and on, it prints per prompt:
- `still s`: seconds after the first half second that the pelvis moves slower than 0.1 m/s;
- `last/first`: ground travel of the last 2 s over that of the first 2 s (0: stopped);
- `skate`: the foot-skating ratio (GMD's definition, motion/physics.py) over the frames that
  move over the ground;
- `pass`: the family's read-outs over the whole clip (eval/readouts.py);
- `peak m/s`: the motion's largest joint speed (a jolt at a seam would lift it above the single
  take's);
- `fired`: how many seeds were remade as takes (the controls must stay at 0);
- `seam/takes`: of the remade motions, the largest joint speed within a seam's blend window
  over the largest of the takes as generated (long_motion.seam_speeds; <= 1: no jolt).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import mlct
from mlct.eval.readouts import evaluate_label
from mlct.generate.compose.keep_going import ground_speed
from mlct.generate.compose.long_motion import LongMotion, seam_speeds
from mlct.motion.physics import foot_skating_mask

LOCOMOTION = [
    ("a person walks forward", {"family": "walk", "params": {"direction": "forward"}}),
    ("a person jogs forward", {"family": "jog", "params": {"direction": "forward"}}),
    ("a person runs forward", {"family": "run", "params": {"direction": "forward"}}),
    ("a person walks backward", {"family": "walk_backward", "params": {}}),
    ("a person walks in a circle to the left", {"family": "circle", "params": {"side": "left"}}),
    ("a person side steps to the right", {"family": "side_step", "params": {"side": "right"}}),
    ("a man strolls down the street", {"family": "walk", "params": {}}),
    ("the woman hurries forward", {"family": "walk", "params": {"speed": "fast"}}),
]
CONTROLS = [
    ("a person jumps", None),
    ("a person waves with the right hand", None),
    ("a person walks forward four steps", None),
    ("a person sits down and stands up", None),
    ("a person performs a long jump forward", None),
    ("someone spins around on the spot to the left", None),
    ("someone turns all the way around to the left", None),
]


def still_seconds(joints: np.ndarray, fps: float) -> float:
    speed = ground_speed(joints, fps)[int(0.5 * fps):]
    return float((speed < 0.1).sum() / fps)


def travel_ratio(joints: np.ndarray, fps: float) -> float:
    root = joints[:, 0, [0, 2]]
    n = int(2 * fps)
    first = np.linalg.norm(np.diff(root[:n], axis=0), axis=1).sum()
    last = np.linalg.norm(np.diff(root[-n:], axis=0), axis=1).sum()
    return float(last / max(first, 1e-6))


def speed_peak(joints: np.ndarray, fps: float) -> float:
    """The largest joint speed of the motion, m/s: a jolt at a seam would lift it above the
    single take's (the same prompt and seed, keep-going off)."""
    return float(np.linalg.norm(np.diff(joints, axis=0), axis=-1).max() * fps)


def moving_skate(joints: np.ndarray, skeleton, fps: float) -> float:
    """The foot-skating ratio over the frames that move over the ground (>= 0.1 m/s): a clip
    that stands still for half its length would otherwise halve its ratio."""
    moving = ground_speed(joints, fps)[1:] >= 0.1
    skating = foot_skating_mask(joints, skeleton)
    return float(skating[moving].mean()) if moving.any() else 0.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--seconds", type=float, nargs="+", default=[7.0, 9.5])


def run(args: argparse.Namespace) -> None:
    pipe = mlct.load(args.model)
    fps = pipe.skeleton.fps
    print(f"{args.seeds} seeds; each cell before -> after (keep-going off -> on)")
    print(f"{'prompt':<42}{'s':>5}{'still s':>14}{'last/first':>13}{'skate':>13}"
          f"{'pass':>11}{'peak m/s':>14}{'fired':>6}{'ms after':>9}{'seam/takes':>11}")
    totals = {"loco_pass": [0, 0, 0], "still": [[], []], "fired_controls": 0, "seam": []}
    for prompts, is_control in ((LOCOMOTION, False), (CONTROLS, True)):
        for text, family in prompts:
            for seconds in args.seconds:
                rows = {"still": ([], []), "ratio": ([], []), "skate": ([], []),
                        "pass": ([], []), "peak": ([], [])}
                seam_ratios = []
                fired, spent = 0, 0.0
                for seed in range(args.seeds):
                    made = []
                    for on in (False, True):
                        pipe.keep_going = on
                        start = time.perf_counter()
                        motion = pipe.generate(text, seconds=seconds, seed=seed)[0]
                        if on:
                            spent += time.perf_counter() - start
                            if isinstance(motion, LongMotion) and motion.seams:
                                speeds = seam_speeds(motion)
                                seam_ratios.append(speeds["seam_max"] / speeds["segments_max"])
                        made.append(motion.joints)
                    changed = np.abs(made[0] - made[1]).max(axis=(1, 2)) > 1e-6
                    fired += bool(changed.any())
                    for k, joints in enumerate(made):
                        rows["still"][k].append(still_seconds(joints, fps))
                        rows["ratio"][k].append(travel_ratio(joints, fps))
                        rows["skate"][k].append(moving_skate(joints, pipe.skeleton, fps))
                        rows["peak"][k].append(speed_peak(joints, fps))
                        if family is not None:
                            label = {"actions": [dict(family, start=0.0, end=seconds)],
                                     "concurrent": None}
                            rows["pass"][k].append(all(p for _, p in evaluate_label(joints,
                                                                                    label)))

                def pair(key: str, fmt: str) -> str:
                    a, b = (np.mean(v) if v else float("nan") for v in rows[key])
                    return f"{a:{fmt}}->{b:{fmt}}"
                print(f"{text[:41]:<42}{seconds:>5.1f}{pair('still', '4.1f'):>14}"
                      f"{pair('ratio', '4.2f'):>13}{pair('skate', '.3f'):>13}"
                      f"{pair('pass', '.1f') if family else '-':>11}{pair('peak', '.2f'):>14}"
                      f"{fired:>6}{spent / args.seeds * 1000:>9.0f}"
                      f"{max(seam_ratios) if seam_ratios else float('nan'):>11.2f}")
                totals["seam"] += seam_ratios
                if is_control:
                    totals["fired_controls"] += fired
                else:
                    totals["still"][0] += rows["still"][0]
                    totals["still"][1] += rows["still"][1]
                    totals["loco_pass"][0] += sum(rows["pass"][0])
                    totals["loco_pass"][1] += sum(rows["pass"][1])
                    totals["loco_pass"][2] += len(rows["pass"][1])
    n = totals["loco_pass"][2]
    print(f"\nlocomotion: still seconds per clip {np.mean(totals['still'][0]):.2f} -> "
          f"{np.mean(totals['still'][1]):.2f}; read-outs pass {totals['loco_pass'][0]}/{n} -> "
          f"{totals['loco_pass'][1]}/{n}; controls remade: {totals['fired_controls']}; largest "
          f"seam speed over its takes' largest: {max(totals['seam'], default=float('nan')):.2f}")
