"""The read-outs on their own ground truth: per family, the share of N procedural motions that
pass the family's checks, how many other families' motions pass them, and (a sided family) how
many of its own motions pass with the other side named.

    python bench/quality.py ground-truth [--families arms] [--per-family 300] [--json OUT]

--families: arms (synth/families_arms.py, version 4), body (families_body.py, version 4), v3
(the families version 3 adds), all, or family names. A family's N motions take its parameter
combinations in turn, motion k with seed k and a style drawn from the benchmark's range
(amplitude and tempo 0.85-1.15): the set tests/test_readouts_arms.py and test_readouts_body.py
take their first motions from, and the one the read-outs' thresholds were set on
(mlct/eval/readouts_arms.py, readouts_body.py). The other families' motions: two seeds (11, 12)
of each of the first six parameter combinations of every family. Also printed: the range of
the peak wrist speed (m/s) over each family's motions, what the swing families' speed test
bounds. A family under 95% is marked "<"; the exit status is 1 if any is, or if another
family's motion passes its checks.

About 20 ms of one core a motion: ~2 min for the arm families at 300, ~7 min for all.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

from mlct.data.synth.actions import FAMILIES, FAMILY_PARAMS, NEW_FAMILIES, Action, Script
from mlct.data.synth.compose import compose
from mlct.data.synth.motions import Style
from mlct.data.synth.rig import make_rig
from mlct.errors import MlctError
from mlct.eval import readouts as ro
from mlct.motion.skeleton import HUMANML3D as SK

RIG = make_rig(SK)
PASS_RATE = 0.95
SIDE_KEYS = ("hand", "leg", "side")
OTHER_SIDE = {"left": "right", "right": "left"}


def combos(family: str) -> list[dict]:
    """Every parameter combination of a family, in FAMILY_PARAMS' order."""
    spec = FAMILY_PARAMS[family]
    return [dict(zip(spec, values)) for values in itertools.product(*spec.values())]


def motion(family: str, params: dict, seed: int = 0,
           corner: tuple[float, float] | None = None) -> np.ndarray:
    """Positions (T, 22, 3) in metres of one action, in a style of the benchmark's range drawn
    from `seed`, or at `corner` (amplitude, tempo) of it (the read-out tests' style corners)."""
    rng = np.random.default_rng([seed, 7])
    amplitude, tempo = float(rng.uniform(0.85, 1.15)), float(rng.uniform(0.85, 1.15))
    if corner is not None:
        amplitude, tempo = corner
    style = Style(amplitude=amplitude, tempo=tempo, arm_length=RIG.arm_length,
                  shoulder_x=RIG.shoulder_x)
    script = Script((Action(family, params),))
    return compose(script, RIG, style, rng, SK.fps).positions / RIG.scale


def passes(readings: dict, family: str, params: dict) -> bool:
    """Whether read-outs (ro.read_all's, made once per motion) pass a family's checks."""
    return all(check(readings) for check in ro.checks_for({"family": family, "params": params}))


def family_set(names: list[str]) -> list[str]:
    from mlct.data.synth import families_arms, families_body

    groups = {"arms": list(families_arms.PARAMS), "body": list(families_body.PARAMS),
              "v3": list(NEW_FAMILIES), "all": list(FAMILIES)}
    out: list[str] = []
    for name in names:
        if name not in groups and name not in FAMILY_PARAMS:
            raise MlctError(f"--families: no family or group {name!r} "
                            f"(groups: {', '.join(groups)})")
        out += [f for f in groups.get(name, [name]) if f not in out]
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--families", nargs="+", default=["arms"])
    parser.add_argument("--per-family", type=int, default=300)
    parser.add_argument("--json", type=Path, default=None)


def run(args: argparse.Namespace) -> None:
    families = family_set(args.families)

    others = [(f, p, ro.read_all(motion(f, p, seed))) for f in FAMILIES for p in combos(f)[:6]
              for seed in (11, 12)]
    report, bad = {}, False
    print(f"{'family':20s} {'passed':>8s}  {'other side':>10s}  {'others pass':>11s}  "
          f"{'wrist m/s':>11s}  failed (params, seed)")
    for family in families:
        cs = combos(family)
        own = [(cs[k % len(cs)], k, ro.read_all(motion(family, cs[k % len(cs)], k)))
               for k in range(args.per_family)]
        passed = [passes(r, family, p) for p, _, r in own]
        rate = float(np.mean(passed))
        sided = [(p, r) for p, _, r in own if any(p.get(key) in OTHER_SIDE for key in SIDE_KEYS)]
        other_side = [passes(r, family, {key: OTHER_SIDE.get(v, v) if key in SIDE_KEYS else v
                                         for key, v in p.items()}) for p, r in sided]
        intruders = sorted({f"{f}({','.join(f'{k}={v}' for k, v in p.items())})"
                            for params in cs for f, p, r in others
                            if f != family and passes(r, family, params)})
        wrist = [r["peak_wrist_speed"] for _, _, r in own]
        failed = [(p, k) for (p, k, _), ok in zip(own, passed) if not ok]
        bad |= rate < PASS_RATE or bool(intruders)
        print(f"{family:20s} {rate:7.1%}{'<' if rate < PASS_RATE else ' '} "
              f"{(f'{np.mean(other_side):.1%}' if sided else '-'):>10s}  {len(intruders):11d}  "
              f"{min(wrist):4.1f}-{max(wrist):4.1f}  "
              + " ".join(f"{'/'.join(map(str, p.values())) or '-'}:{k}" for p, k in failed[:8])
              + (" ..." if len(failed) > 8 else ""))
        if intruders:
            print(f"{'':20s} passed by: {', '.join(intruders)}")
        report[family] = {"motions": len(own), "pass_rate": rate,
                          "other_side_pass_rate": float(np.mean(other_side)) if sided else None,
                          "other_families_passing": intruders,
                          "peak_wrist_speed": [float(min(wrist)), float(max(wrist))],
                          "failed": [{"params": p, "seed": k} for p, k in failed]}
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=1))
    if bad:
        sys.exit(1)
