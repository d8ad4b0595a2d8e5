"""Prompts of three actions in turn: does the motion do all three, in order?

    python bench/three_actions.py [--seeds 3] [--no-site]     # ~5 minutes on 2 cores

The 16 prompts of bench/data/quality_prompts_three_actions.json (written by hand before any
run on them), each at the length generate() gives it when none is asked (5 s or as long as its
actions take), made three ways in one run: `mlct generate`'s default (best of the critic's 8),
one sample, and the static site's page (its graphs in Python, serve/site/reference.py, best of
8). Judged as bench/motion_quality.py judges two-action prompts: in order at the motion's own
cuts (mlct.eval.readouts.evaluate_in_order: each action in its window, the windows chosen
where the motion passes most) and in equal thirds. Prints each way's pass rates and, for the
default, the prompts that failed and the checks they failed.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from motion_quality import Tally, judge_prompt  # noqa: E402

import mlct  # noqa: E402

PROMPTS = Path(__file__).resolve().parent / "data" / "quality_prompts_three_actions.json"
NFE = 5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--no-site", action="store_true", help="skip the static site's row")
    args = parser.parse_args()
    torch.set_num_threads(1)
    items = json.loads(PROMPTS.read_text(encoding="utf-8"))["three_actions"]
    pipe = mlct.load()
    fps = pipe.skeleton.fps
    ways = {"mlct generate (best of 8)": lambda text, seed: pipe.generate(
                text, nfe=NFE, seed=seed)[0].joints,
            "mlct generate, 1 sample": lambda text, seed: pipe.generate(
                text, nfe=NFE, seed=seed, candidates=1)[0].joints}
    with tempfile.TemporaryDirectory() as tmp:
        if not args.no_site:
            from mlct.serve.site import export_site, load_site_reference
            from mlct.serve.site.reference import generate_with_portable_noise

            site = load_site_reference(export_site("bundled", Path(tmp) / "site"), threads=1)
            ways["the page (best of 8)"] = lambda text, seed: generate_with_portable_noise(
                site, text, None, NFE, seed)[1]
        print(f"{len(items)} three-action prompts x {args.seeds} seeds, the default length, "
              f"{NFE} NFE")
        for name, make in ways.items():
            in_order, thirds = Tally(), Tally()
            failed: dict[str, list[str]] = defaultdict(list)
            for seed in range(args.seeds):
                for k, item in enumerate(items):
                    joints = make(item["text"], seed * 1000 + k)
                    label, results = judge_prompt(joints, item["actions"], len(joints) / fps)
                    if not in_order.add(label, results):
                        failed[item["text"]] += [n for n, ok in results if not ok]
                    thirds.add(*judge_prompt(joints, item["actions"], len(joints) / fps,
                                             halves=True))
            print(f"{name}: in order {in_order.summary()['overall']:.3f}, in thirds "
                  f"{thirds.summary()['overall']:.3f} ({in_order.summary()['motions']} motions)",
                  flush=True)
            if name.startswith("mlct generate (best"):
                for text, checks in sorted(failed.items()):
                    print(f"    failed: {text!r}: {', '.join(sorted(set(checks)))}")


if __name__ == "__main__":
    main()
