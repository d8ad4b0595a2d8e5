"""Does a model make an action as many times as its text says? Counts asked against counts made.

    python bench/count_following.py [--model DIR] [--seeds 5] [--data BENCHMARK]

For every family of the procedural benchmark that takes a count (claps, waves, hops, jumps,
squats, punches, kicks) and every count the benchmark uses, one prompt phrased as its captions
are ("a person claps their hands four times."), generated at the length the benchmark's
single-action clips of that family and count have on average (--data; 1.2 s a repetition
without it), --seeds seeds, the model's default sampling (best of N with its critic). Each
motion is judged by the read-outs of bench/motion_quality.py on its label: the count check
alone ("count"), and every check of the action ("all"). A model that draws the mean count
passes the middle counts and fails the ends; the table shows which.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

import mlct
from mlct.eval.readouts import evaluate_label

_TIMES = {1: "once", 2: "twice", 3: "three times", 4: "four times", 5: "five times"}

# family -> (prompt with {t} for the count adverb, the label's other parameters, the counts the
# benchmark draws: data/synth/actions.py)
PROMPTS: dict[str, tuple[str, dict[str, Any], tuple[int, ...]]] = {
    "clap": ("a person claps their hands {t}.", {}, (2, 3, 4, 5)),
    "wave": ("a person waves their right hand {t}.", {"hand": "right"}, (2, 3, 4)),
    "hop": ("a person hops on their left leg {t}.", {"leg": "left"}, (2, 3, 4, 5)),
    "jump": ("a person jumps in place {t}.", {"mode": "in_place"}, (1, 2, 3)),
    "squat": ("a person squats down {t}.", {}, (1, 2, 3)),
    "punch": ("a person punches with their left hand {t}.", {"hand": "left"}, (1, 2, 3)),
    "kick": ("a person kicks with their right leg {t}.", {"leg": "right"}, (1, 2)),
}


def clip_seconds(data: Path | None) -> dict[tuple[str, int], float]:
    """(family, count) -> mean length in seconds of the benchmark's single-action clips of it."""
    if data is None:
        return {}
    from mlct.data.layout import DatasetLayout
    from mlct.eval.judge.action_classifier import read_labels

    layout, labels = DatasetLayout.existing(data), read_labels(data)
    lengths: dict[tuple[str, int], list[int]] = defaultdict(list)
    for name in layout.read_split("train"):
        label = labels.get(name)
        if not label or len(label["actions"]) != 1 or label.get("concurrent"):
            continue
        action = label["actions"][0]
        if "count" in action.get("params", {}):
            lengths[(action["family"], action["params"]["count"])].append(label["frames"])
    return {key: float(np.mean(v)) / 20.0 for key, v in lengths.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default=None, help="default: the bundled model")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--data", type=Path, default=None,
                        help="a procedural benchmark, for the clip lengths")
    args = parser.parse_args()
    gen = mlct.load(args.model)
    seconds = clip_seconds(args.data)
    print(f"{'family':<8}{'count':>6}{'seconds':>9}{'count ok':>10}{'all ok':>8}")
    totals: dict[str, list[int]] = {"count": [0, 0], "all": [0, 0]}
    for family, (template, params, counts) in PROMPTS.items():
        for count in counts:
            length = seconds.get((family, count), 1.2 * count + 1.0)
            prompt = template.format(t=_TIMES[count])
            label = {"actions": [{"family": family, "params": {**params, "count": count},
                                  "start": 0.0, "end": length}], "concurrent": None}
            motions = gen.generate([prompt] * args.seeds, seconds=length,
                                   seed=list(range(args.seeds)))
            results = [evaluate_label(m.joints, label) for m in motions]
            count_ok = [all(p for name, p in r if "count" in name) for r in results]
            all_ok = [all(p for _, p in r) for r in results]
            for key, oks in (("count", count_ok), ("all", all_ok)):
                totals[key][0] += sum(oks)
                totals[key][1] += len(oks)
            print(f"{family:<8}{count:>6}{length:>9.1f}{np.mean(count_ok):>10.2f}"
                  f"{np.mean(all_ok):>8.2f}")
    print(f"all counts: count check {totals['count'][0]}/{totals['count'][1]} = "
          f"{totals['count'][0] / totals['count'][1]:.3f}; every check {totals['all'][0]}/"
          f"{totals['all'][1]} = {totals['all'][0] / totals['all'][1]:.3f}")


if __name__ == "__main__":
    main()
