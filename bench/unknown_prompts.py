"""How often the unknown-prompt notice is right: how many prompts the model cannot do it flags,
and how few it flags of the prompts the model can do.

    python bench/unknown_prompts.py [--model MODEL_DIR] [--data SYNTH] [--passes SEEDS]

A prompt is flagged when some part of it lies too far from every training caption
(generate/compose/unknown_prompts.py: its cosine with the nearest one under UNKNOWN_BELOW). The sets:

tuning (they chose UNKNOWN_BELOW; the rule is printed and applied again here):
  unknown  bench/data/unknown_prompts.json "tuning": 30 everyday activities no family covers
  known    the benchmark's validation captions; the seen paraphrases and two-action prompts
           (bench/data/quality_prompts.json); held-out paraphrase sets 1-3
held out (they chose nothing):
  unknown  bench/data/unknown_prompts.json "held_out": 47 other activities, other words
  known    the benchmark's test captions (all 3 of each test motion); held-out paraphrase sets
           4-7 and the three-action prompts, rewordings of known actions by authors who had not
           read the captions; new captions of the test motions in the everyday, colloquial,
           short and context vocabularies (data/synth: words the model was trained on, said of
           motions it was not)

The benchmark is the bundled model's, `mlct data synth --num 4000 --seed 0 --benchmark-version 2`
(tools/recipe_stage.sh); its validation and test motions are remade here (their captions
depend only on the seed and the motion's index), or read from --data. --passes N also makes
each held-out paraphrase N times (4 s, as `bench/quality.py paraphrases`) and prints how often
its read-outs pass, flagged and not: whether a flagged rewording is one the model gets wrong.

How the threshold was chosen: the unknown prompts (both sets) were written before any figure
was measured; the rule "the lowest threshold that flags 90 % of the tuning set's unknown
prompts" was fixed on the tuning columns. A first sweep of thresholds printed the held-out
columns beside them before the rule was fixed, so these were seen, not chosen on; nothing was
changed after the held-out figures below were printed. Logged in
docs/logs/unknown_prompts_2026-12-02.txt.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

import mlct
from mlct.data.synth.build import _split, make_motion
from mlct.data.synth.rephrase import everyday_captions
from mlct.generate.compose.unknown_prompts import UNKNOWN_BELOW, unknown_below
from mlct.motion.skeleton import get_skeleton

DATA = Path(__file__).parent / "data"
UNKNOWN = DATA / "unknown_prompts.json"
# the bundled model's benchmark (tools/recipe_stage.sh): version 2
BENCHMARK = {"num": 4000, "seed": 0, "version": 2}
VOCABULARIES = ("everyday", "colloquial", "short", "context")
TUNING_SHARE = 0.90  # of the tuning set's unknown prompts the threshold must flag


def paraphrases(name: str, key: str = "paraphrases") -> list[dict[str, Any]]:
    return json.loads((DATA / f"quality_prompts{name}.json").read_text(encoding="utf-8"))[key]


def split_records(data: Path | None, split: str) -> list[dict[str, Any]]:
    """The benchmark's labels.jsonl records of a split (each with its "captions")."""
    if data is not None:
        from mlct.data.labels import read_labels
        from mlct.data.layout import read_split

        labels = read_labels(data)
        return [labels[n] for n in read_split(data, split) if n in labels]
    skeleton = get_skeleton("humanml3d")
    names = [f"{i:06d}" for i in range(BENCHMARK["num"])]
    torch.set_num_threads(1)  # one clip's inverse kinematics: threads cost more than they give
    return [make_motion(int(n), BENCHMARK["seed"], skeleton, BENCHMARK["version"]).label
            for n in _split(names, BENCHMARK["seed"])[split]]


def nearest(pipe: Any, texts: list[str], split: bool = True) -> np.ndarray:
    """Each prompt's lowest part cosine with its nearest training caption (generate()'s
    parts: a prompt is flagged when any part is)."""
    from mlct.generate.compose.reading import parts_as_made
    from mlct.generate.compose.lengths import stated_lengths
    from mlct.generate.compose.prompts import clean_prompt

    clean, _ = stated_lengths([clean_prompt(t) for t in texts], split)
    plans = [[*body, *([arms] if arms else [])]
             for body, arms in (parts_as_made(t, split) for t in clean)]
    distinct = list(dict.fromkeys(p for plan in plans for p in plan))
    cos = {}
    for start in range(0, len(distinct), 256):
        chunk = distinct[start:start + 256]
        cos.update(zip(chunk, pipe.known_anchors.nearest(pipe.encode_text(chunk)).tolist()))
    return np.array([min(cos[p] for p in plan) for plan in plans])


def tuned_threshold(unknown: np.ndarray) -> float:
    """The lowest cosine, in hundredths, under which TUNING_SHARE of `unknown` lie."""
    need = math.ceil(TUNING_SHARE * len(unknown))
    return math.floor(np.sort(unknown)[need - 1] * 100 + 1) / 100


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--data", type=Path, default=None,
                        help="the benchmark's folder (default: its val and test motions remade)")
    parser.add_argument("--passes", type=int, default=0,
                        help="seeds per held-out paraphrase for the read-outs (default: none)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()

    started = time.perf_counter()
    pipe = mlct.load(args.model, backend="torch")
    if pipe.known_anchors is None:
        raise SystemExit("this model has no text anchors to judge prompts by")
    unknown = json.loads(UNKNOWN.read_text(encoding="utf-8"))
    val, test = split_records(args.data, "val"), split_records(args.data, "test")
    rng = np.random.default_rng(20261202)
    tuning = {"unknown (tuning)": unknown["tuning"],
              "benchmark val captions": [c for r in val for c in r["captions"]],
              "seen paraphrases": [p["text"] for p in paraphrases("")],
              "seen two-action prompts": [p["text"] for p in paraphrases("", "two_actions")],
              **{f"held-out paraphrases {k}": [p["text"] for p in paraphrases(f"_heldout{s}")]
                 for k, s in ((1, ""), (2, "2"), (3, "3"))}}
    held = {"unknown (held out)": unknown["held_out"],
            "benchmark test captions": [c for r in test for c in r["captions"]],
            **{f"held-out paraphrases {k}": [p["text"] for p in paraphrases(f"_heldout{k}")]
               for k in (4, 5, 6, 7)},
            "three-action prompts": [p["text"] for p in paraphrases("_three_actions",
                                                                     "three_actions")],
            **{f"test motions, {v} words": [c for r in test
                                            for c in everyday_captions(r, rng, 1, v)]
               for v in VOCABULARIES}}
    cos = {name: nearest(pipe, texts) for name, texts in {**tuning, **held}.items()}

    chosen = tuned_threshold(cos["unknown (tuning)"])
    shipped = unknown_below(pipe.known_anchors)
    print(f"rule: flag a prompt when a part's cosine with its nearest training caption is under "
          f"the threshold; threshold = the lowest (in hundredths) that flags "
          f"{TUNING_SHARE:.0%} of the tuning set's unknown prompts")
    print(f"tuned on the tuning sets: {chosen:.2f}; the model uses {shipped:.2f}"
          f"{'' if shipped == UNKNOWN_BELOW else ' (its anchors say so)'}")
    print(f"\ntuning sets, flagged at thresholds around it:")
    grid = [round(chosen + d, 2) for d in (-0.06, -0.04, -0.02, 0.0, 0.02, 0.04)]
    print(f"{'set':34s}{'n':>6s}" + "".join(f"{t:>7.2f}" for t in grid))
    for name in tuning:
        print(f"{name:34s}{len(cos[name]):>6d}"
              + "".join(f"{np.mean(cos[name] < t):>7.1%}" for t in grid))

    rates: dict[str, dict[str, Any]] = {}
    print(f"\nat {shipped:.2f}: flagged")
    print(f"{'set':34s}{'n':>6s}{'flagged':>9s}{'share':>8s}   nearest cosine 5% / 50% / 95%")
    for group, sets in (("tuning", tuning), ("held out", held)):
        print(f"-- {group}")
        for name in sets:
            flagged = cos[name] < shipped
            q = np.quantile(cos[name], [0.05, 0.5, 0.95])
            rates[name] = {"n": int(len(flagged)), "flagged": int(flagged.sum()),
                           "share": float(flagged.mean()), "group": group}
            print(f"{name:34s}{len(flagged):>6d}{int(flagged.sum()):>9d}{flagged.mean():>8.1%}"
                  f"   {q[0]:.3f} / {q[1]:.3f} / {q[2]:.3f}")
    missed = [t for t, c in zip(held["unknown (held out)"], cos["unknown (held out)"])
              if c >= shipped]
    print(f"\nheld-out unknown prompts not flagged: {missed}")
    flagged_known = [(t, round(float(c), 3)) for name in held if not name.startswith("unknown")
                     and "paraphrases" in name
                     for t, c in zip(held[name], cos[name]) if c < shipped]
    print(f"held-out paraphrases flagged ({len(flagged_known)}): {flagged_known}")

    report: dict[str, Any] = {"threshold": shipped, "tuned": chosen, "rates": rates}
    if args.passes:
        report["passes"] = passes_by_flag(pipe, cos, shipped, args.passes)
    print(f"\n({time.perf_counter() - started:.0f} s)")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))


def passes_by_flag(pipe: Any, cos: dict[str, np.ndarray], below: float, seeds: int
                   ) -> dict[str, Any]:
    """The held-out paraphrases' read-out pass rate (the read-outs' judge, eval/suites, 4 s),
    the flagged apart from the rest."""
    from mlct.eval.suites.common import prompt_passes

    items, flags = [], []
    for k in (4, 5, 6, 7):
        set_items = paraphrases(f"_heldout{k}")
        items += set_items
        flags += (cos[f"held-out paraphrases {k}"] < below).tolist()
    passed = prompt_passes(pipe, items, [4.0] * len(items), seeds) / seeds
    flags = np.array(flags)
    out = {}
    print(f"\nheld-out paraphrases 4-7, read-outs passed over {seeds} seed(s) at 4 s:")
    for name, mask in (("flagged", flags), ("not flagged", ~flags)):
        share = float(passed[mask].mean()) if mask.any() else float("nan")
        out[name] = {"prompts": int(mask.sum()), "passed": share}
        print(f"  {name:12s} {int(mask.sum()):>4d} prompts  passed {share:.3f}")
    return out


if __name__ == "__main__":
    main()
