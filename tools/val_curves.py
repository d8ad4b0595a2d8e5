"""Validation curves of several runs side by side, step by step, from their log.jsonl.

    python tools/val_curves.py RUN_OR_LOG [RUN_OR_LOG ...] [--labels a b] [--parts consistency denoise]
        [--every 1000]

An ablation of a training recipe (a learning rate, dropout, a smaller network) is read first
from its curve against the run it changes: where one run's curve sits above the other's from the
first thousand steps, the physical read-outs (bench/motion_quality.py) are worth a run only at
the end. Each argument is a log.jsonl file or a run folder (WORK/RUN, or WORK/RUN/STAGE) holding
one; each row is a validated step, a column per run, "-" where a run has no validation there.
Losses are read, not recomputed: runs on different autoencoders share a scale only roughly.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def find_log(path: Path) -> Path:
    """The log.jsonl of a run: the file itself, RUN/log.jsonl or the only RUN/*/log.jsonl."""
    if path.is_file():
        return path
    if (path / "log.jsonl").is_file():
        return path / "log.jsonl"
    logs = sorted(path.glob("*/log.jsonl"))
    if len(logs) != 1:
        found = ", ".join(str(p) for p in logs) or "none"
        raise SystemExit(f"error: {path}: expected one log.jsonl, found {found}")
    return logs[0]


def validation_points(log: Path, parts: list[str]) -> dict[int, list[float]]:
    """step -> [val_loss, val_<part>...] for every validation line of one log; should a step
    appear twice (logs joined by hand), the later line wins."""
    points: dict[int, list[float]] = {}
    for line in log.read_text().splitlines():
        if not line.strip():
            continue
        record = json.loads(line)
        if "val_loss" not in record:
            continue
        points[int(record["step"])] = [float(record["val_loss"])] + [
            float(record.get(f"val_{part}", float("nan"))) for part in parts]
    return points


def table(curves: list[dict[int, list[float]]], every: int) -> list[tuple[int, list[str]]]:
    """(step, one cell per run) for the steps any run validated that are multiples of every."""
    steps = sorted({s for curve in curves for s in curve if s % every == 0})
    return [(s, ["/".join(f"{v:.3f}" for v in curve[s]) if s in curve else "-"
                 for curve in curves]) for s in steps]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--labels", nargs="+", default=None, help="one per run (default: paths)")
    parser.add_argument("--parts", nargs="*", default=[],
                        help="loss terms printed after the total, e.g. consistency denoise")
    parser.add_argument("--every", type=int, default=500, help="only steps divisible by this")
    args = parser.parse_args()
    if args.labels is not None and len(args.labels) != len(args.runs):
        raise SystemExit(f"error: {len(args.labels)} labels for {len(args.runs)} runs")
    if args.every < 1:
        raise SystemExit("error: --every must be at least 1")
    labels = args.labels or [str(r) for r in args.runs]
    curves = [validation_points(find_log(run), args.parts) for run in args.runs]
    cells = "/".join(["val_loss"] + args.parts)
    print(f"# {cells} by step; " + "; ".join(f"[{i}] {label}" for i, label in enumerate(labels)))
    rows = table(curves, args.every)
    width = max([12] + [len(c) for _, row in rows for c in row])
    print(f"{'step':>7}  " + "  ".join(f"{f'[{i}]':>{width}}" for i in range(len(labels))))
    for step, row in rows:
        print(f"{step:>7}  " + "  ".join(f"{c:>{width}}" for c in row))


if __name__ == "__main__":
    main()
