"""Short prompts: does "a woman waves" wave? Bare verbs, four subjects, read-outs.

People type the shortest sentence that says the action: "a person walks", "someone stretches",
"a man kicks". The benchmark's captions and bench/data's paraphrases name the side, the count
or the manner, so they never ask this. This bench makes each action family's bare-verb prompt
with four subjects, and a few short two-action prompts, for each --model, same seeds, one run,
and prints the read-out pass rates side by side. What the prompt leaves out is not judged: a
bare "waves" passes with a left, a right or a two-handed wave (whichever the motion's
read-outs pass), "kicks" with either leg. Two actions are judged in order at the motion's own
cut (readouts.evaluate_in_order).

    python bench/quality.py short [--model DIR ...] [--seeds 5] [--seconds 5] [--candidates N]
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path
from typing import Any

import mlct
import mlct.generate.compose.durations as durations
from mlct.eval.readouts import evaluate_in_order, evaluate_label

SUBJECTS = ("a person", "a woman", "a man", "someone")
# family -> the bare verb phrase
SINGLE = {
    "walk": "walks", "jog": "jogs", "run": "runs", "walk_backward": "walks backward",
    "side_step": "steps sideways", "jump": "jumps", "hop": "hops", "squat": "squats",
    "kneel": "kneels", "sit_stand": "sits down and stands up", "bow": "bows",
    "stretch": "stretches", "clap": "claps", "wave": "waves", "punch": "punches",
    "kick": "kicks", "spin": "spins around", "raise_arms": "raises both arms",
    "turn": "turns left", "circle": "walks in a circle to the right",
}
# what a short prompt does name
NAMED = {"turn": {"side": "left"}, "circle": {"side": "right"}}
PAIRS = (("walk", "walks", "wave", "waves"), ("jump", "jumps", "bow", "bows"),
         ("squat", "squats", "clap", "claps"), ("walk", "walks", "kick", "kicks"),
         ("stretch", "stretches", "jump", "jumps"), ("run", "runs", "wave", "waves"))
# what a bare verb leaves open: any of these values may be what the motion did
OPEN = {"wave": {"hand": ("left", "right", "both")}, "raise_arms": {"hand": ("both",)}}


def readings_of(family: str) -> list[dict[str, Any]]:
    """Every way the bare verb may be meant, as labels.jsonl actions."""
    options = OPEN.get(family, {})
    return [{"family": family, "params": {**NAMED.get(family, {}), **dict(zip(options, values))}}
            for values in itertools.product(*options.values())]


def judged(joints: Any, families: list[str], fps: float) -> bool:
    for actions in itertools.product(*(readings_of(f) for f in families)):
        if len(actions) == 1:
            label = {"actions": [dict(actions[0], start=0.0, end=len(joints) / fps)],
                     "concurrent": None}
            results = evaluate_label(joints, label)
        else:
            results = evaluate_in_order(joints, list(actions))
        if all(ok for _, ok in results):
            return True
    return False


def prompts() -> list[tuple[str, list[str]]]:
    out = [(f"{s} {verb}", [family]) for family, verb in SINGLE.items() for s in SUBJECTS]
    out += [(f"{s} {v1}, then {v2}", [f1, f2]) for f1, v1, f2, v2 in PAIRS for s in SUBJECTS]
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", type=Path, action="append", default=None,
                        help="a model folder (repeat to compare; default: the bundled model)")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--candidates", type=int, default=None,
                        help="best-of-N by the model's critic (default: the model's; 1 = plain)")
    parser.add_argument("--pairs", action="store_true", help="the two-action prompts only")
    parser.add_argument("--squeeze-alike", action="store_true",
                        help="squeeze a sequence's parts alike however short the clip (the rule "
                             "before generate/compose/durations.py's FASTEST_TEMPO_SHARE), to compare")


def run(args: argparse.Namespace) -> None:
    if args.squeeze_alike:
        durations.FASTEST_TEMPO_SHARE = 0.0  # never past the data's tempi: alike, as before
    models = args.model or [None]
    items = [item for item in prompts() if len(item[1]) > 1 or not args.pairs]
    rows: dict[str, list[list[int]]] = {}
    for column, model in enumerate(models):
        gen = mlct.load(model, backend="torch")
        for seed in range(args.seeds):
            made = gen.generate([text for text, _ in items], seconds=args.seconds,
                                seed=seed * 100_000, candidates=args.candidates)
            for (text, families), motion in zip(items, made):
                key = " + ".join(families) if len(families) > 1 else families[0]
                row = rows.setdefault(key, [[0, 0] for _ in models])
                row[column][0] += judged(motion.joints, families, gen.skeleton.fps)
                row[column][1] += 1
    names = [str(m) if m else "bundled" for m in models]
    print(f"{len(items)} short prompts ({len(SUBJECTS)} subjects each), {args.seeds} seeds, "
          f"{args.seconds:g} s, candidates {args.candidates or 'default'}, a sequence's parts "
          f"squeezed {'alike' if args.squeeze_alike else 'as generate/compose/durations.py does'}; "
          "read-out pass rates")
    print(f"{'family':<22}" + "".join(f"{n[-22:]:>24}" for n in names))
    totals = [[0, 0] for _ in models]
    for key, row in rows.items():
        print(f"{key:<22}" + "".join(f"{f'{ok}/{n}  {ok / n:.2f}':>24}" for ok, n in row))
        for total, (ok, n) in zip(totals, row):
            total[0] += ok
            total[1] += n
    print(f"{'all':<22}" + "".join(f"{ok / n:>24.3f}" for ok, n in totals))
