"""The everyday vocabulary (bench/data/vocabulary.json): which actions the training data covers,
and how a model does on one prompt per action.

    python bench/vocabulary.py [--real DATASET ...] [--model MODEL] [--seeds 1] [--seconds 4]
        [--critic-margin M] [--failures]

Coverage: an action is covered by real capture when a dataset given with --real (imported with
`mlct data import --corpus ...`, its provenance.jsonl) holds a training motion of one of its
labels; by the procedural benchmark when a family makes it. Without --real the real column
counts no dataset, only what the list says exists ("listed").

With --model: each action's prompt generated once per seed (seed s * 100,000, as the quality
suites do), judged by the read-outs where the procedural labels give some (the actions
without a family have no read-out yet), and whether the model says it does not know the prompt.
Prints one table per category and the totals; a few seconds a seed on 2 cores. With
--failures, also each judged action that failed a seed, with the read-outs it missed.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter, defaultdict
from pathlib import Path

VOCABULARY = Path(__file__).with_name("data") / "vocabulary.json"


def real_labels(datasets: list[Path]) -> dict[str, int]:
    """'corpus:label' -> training motions of it, over the datasets' provenance.jsonl."""
    from mlct.data.layout import provenance_label, read_provenance, read_split

    counts: dict[str, int] = defaultdict(int)
    for root in datasets:
        train = set(read_split(root / "train.txt"))
        for record in read_provenance(root):
            if record["name"] in train:
                counts[f"{record['corpus']}:{provenance_label(record)}"] += 1
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--real", type=Path, nargs="*", default=[],
                        help="real datasets (with provenance.jsonl) the model trains on")
    parser.add_argument("--model", default=None, help="a model folder, or 'bundled'")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--critic-margin", type=float, default=None,
                        help="the critic's margin (default: the model's; 0 = the best of N)")
    parser.add_argument("--failures", action="store_true",
                        help="list the failed actions and the read-outs each one missed")
    args = parser.parse_args()

    actions = json.loads(VOCABULARY.read_text(encoding="utf-8"))["actions"]
    present = real_labels(args.real)
    rows: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    missed: dict[str, Counter] = defaultdict(Counter)  # action -> read-out -> seeds it failed
    for a in actions:
        real = sum(present.get(label, 0) for label in a["real"])
        a["real_motions"] = real
        kind = ("both" if real and a["procedural"] else "real" if real else
                "procedural" if a["procedural"] else "missing")
        for key in (a["category"], "all"):
            rows[key][kind] += 1
            rows[key]["listed_real"] += bool(a["real"])
            rows[key]["n"] += 1

    if args.model is not None:
        import mlct
        from mlct.eval.suites.common import judge_prompt, set_critic_margin

        pipe = mlct.load(None if args.model == "bundled" else args.model)
        set_critic_margin(pipe, args.critic_margin)
        prompts = [a["prompt"] for a in actions]
        unknown = [bool(p) for p in pipe.unknown_parts(prompts)]
        for seed in range(args.seeds):
            made = pipe.generate(prompts, seconds=args.seconds, seed=seed * 100_000)
            for a, motion, flagged in zip(actions, made, unknown):
                for key in (a["category"], "all"):
                    rows[key]["flagged"] += flagged and seed == 0
                    if a["procedural"]:
                        _, results = judge_prompt(motion.joints, a["procedural"],
                                                  motion.joints.shape[0] / pipe.skeleton.fps)
                        rows[key]["judged"] += 1
                        rows[key]["passed"] += all(ok for _, ok in results)
                    if key == "all" and a["procedural"]:
                        missed[a["action"]].update(name for name, ok in results if not ok)

    print(f"vocabulary: {len(actions)} actions ({VOCABULARY.name}); real data: "
          f"{', '.join(str(p) for p in args.real) or 'none given'}; model: {args.model or '-'}")
    header = f"{'category':18s} {'n':>4s} {'real':>5s} {'proc':>5s} {'both':>5s} " \
             f"{'missing':>7s} {'covered':>8s} {'listed real':>11s}"
    if args.model is not None:
        header += f" {'read-outs passed':>17s} {'said unknown':>12s}"
    print(header)
    for key in sorted(k for k in rows if k != "all") + ["all"]:
        r = rows[key]
        covered = r["real"] + r["procedural"] + r["both"]
        line = (f"{key:18s} {r['n']:4d} {r['real']:5d} {r['procedural']:5d} {r['both']:5d} "
                f"{r['missing']:7d} {covered:4d} ({covered / r['n']:4.0%}) {r['listed_real']:6d}")
        if args.model is not None:
            rate = f"{r['passed']}/{r['judged']}" if r["judged"] else "-"
            line += f" {rate:>17s} {r['flagged']:12d}"
        print(line)
    missing = [a["action"] for a in actions if not a["real_motions"] and not a["procedural"]]
    print(f"missing ({len(missing)}): {', '.join(missing)}")
    if args.failures:
        failed = [a for a in actions if missed.get(a["action"])]
        print(f"\nfailed read-outs ({len(failed)} actions; seeds failed of {args.seeds}):")
        for a in failed:
            checks = ", ".join(f"{name} {n}" for name, n in missed[a["action"]].most_common())
            print(f"  {a['action']:28s} {a['prompt']!r}: {checks}")


if __name__ == "__main__":
    main()
