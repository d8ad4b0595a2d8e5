"""How long a recipe's trainings took, from the wall times in their TensorBoard logs.

    python tools/recipe_time.py WORK_DIR [--runs run noise cm dnoise] [--gap-minutes 10]

A recipe (tools/make_bundled_model*.sh) may run in parts: stopped with its session and resumed
later, or beside other jobs. Every run under WORK_DIR with a tb/ folder (WORK/RUN/STAGE/tb) is
read (or the --runs named): the time between consecutive logged steps of one process, where
that interval is under --gap-minutes, counts as training; longer intervals are pauses (a
stopped session) and are listed, not counted. What a resume replays (the steps after the last checkpoint) counts again,
as it was spent again. Start-up before the first logged step (data loading, the text cache) is
not in the logs and not counted: a few seconds to a minute per part.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def stage_time(tb: Path, gap_s: float) -> tuple[float, int, list[float], int]:
    """(seconds of training, last step, pauses in seconds, processes) of one stage's tb/."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    seconds, last_step, pauses = 0.0, 0, []
    files = sorted(tb.glob("events.out.tfevents.*"))
    for events in files:  # one file per process: a resumed stage adds one
        accumulator = EventAccumulator(str(events), size_guidance={"scalars": 0})
        accumulator.Reload()
        tags = accumulator.Tags()["scalars"]
        tag = "loss" if "loss" in tags else (tags[0] if tags else None)
        if tag is None:
            continue
        points = sorted((e.wall_time, e.step) for e in accumulator.Scalars(tag))
        for (t0, _), (t1, _) in zip(points, points[1:]):
            if t1 - t0 < gap_s:
                seconds += t1 - t0
            else:
                pauses.append(t1 - t0)
        if points:
            last_step = max(last_step, points[-1][1])
    return seconds, last_step, pauses, len(files)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("work", type=Path)
    parser.add_argument("--runs", nargs="+", default=None, help="only these runs of WORK_DIR")
    parser.add_argument("--gap-minutes", type=float, default=10.0)
    args = parser.parse_args()
    total = 0.0
    print(f"{'stage':<24} {'steps':>7} {'minutes':>8} {'processes':>9}  pauses (min)")
    for tb in sorted(args.work.glob("*/*/tb"), key=lambda p: p.stat().st_mtime):
        if args.runs is not None and tb.parent.parent.name not in args.runs:
            continue
        seconds, step, pauses, processes = stage_time(tb, args.gap_minutes * 60)
        total += seconds
        name = f"{tb.parent.parent.name}/{tb.parent.name}"
        print(f"{name:<24} {step:>7} {seconds / 60:>8.1f} {processes:>9}  "
              + (", ".join(f"{p / 60:.0f}" for p in pauses) or "-"))
    print(f"{'trainings in all':<24} {'':>7} {total / 60:>8.1f}  ({total / 3600:.2f} h)")


if __name__ == "__main__":
    main()
