"""Do the static site's motions still do what their text says? The read-out pass rate of the
site's own motions (its graphs, in Python: load_site_reference, the same portable noise as the
page) on the benchmark's hand-written paraphrases, per text-encoder / denoiser choice of
`mlct export-web`, next to the torch pipeline's.

    python bench/web_readouts.py [--seeds 3]     # about 10 minutes on 2 busy cores
    python bench/web_readouts.py --two-actions --seeds 5   # the page's sequences (~2 minutes)
    python bench/web_readouts.py --captions DATA --seeds 2  # the test captions (~15 minutes)
    python bench/web_readouts.py --hand-written --seeds 3   # the three paraphrase sets (~10 min)

Each variant makes every paraphrase of bench/data/quality_prompts.json (4 s, 5 NFE) with
--seeds seeds, and scores it as bench/quality.py motion does (mlct.eval.readouts.evaluate_label
on the label the prompt implies); "named side" is the pass rate of the prompts that name a side,
the ones the side contrast (text/sides.py) serves and text-encoder error hurts most. The torch
row is mlct.load()'s pipeline with its own (torch) noise: the same seeds are other motions
there, so its row differs by sampling noise too. The site's graphs store the same numbers
gzipped or not (serve/site/pack.py), so --no-gzip needs no row.

--two-actions scores the benchmark's two-action prompts (7 s) and --captions DATA a procedural
benchmark's test captions (their own lengths, judged by their labels as bench/quality.py motion's
(c), per kind: one action, a sequence, and locomotion with an arm action at the same time,
"+ concurrent"), each made five ways in one run (`makers`): the page before it followed
generate() (the int8 text encoder, the whole prompt given to the model at once, one sample);
the page now (the int8-weights text encoder; a sequence one part per action, chained; an arm
action during another made apart and re-attached; static/compose.js, chain.js) at one sample
and at the model's best of 8 by its critic; and the torch pipeline at both. Two-action prompts
are judged as bench/quality.py motion judges them: in order at the motion's own cut, and in
halves. --hand-written does the same for the three sets of hand-written one-action prompts
(seen paraphrases, held-out, held-out 2) at the length each way gives a prompt asked for none.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Callable

import numpy as np
import torch

import mlct
from mlct.eval.readouts import evaluate_label
from mlct.eval.suites.common import (MAX_FRAMES, PROMPT_FILES, Tally, judge_prompt, print_table,
                                     prompt_label)
from mlct.serve.site import export_site, load_site_reference
from mlct.serve.site.reference import generate_with_portable_noise

DATA = Path(__file__).resolve().parent / "data"  # the hand-written prompt sets
PROMPTS, HELDOUT, HELDOUT2 = (DATA / PROMPT_FILES[k] for k in ("seen", "held-out 1",
                                                                "held-out 2"))

VARIANTS = {"site: --text-encoder float32": {"text_encoder": "float32"},
            "site: default (int8 text encoder, float16 denoiser)": {},
            "site: --denoiser int8": {"denoiser": "int8"},
            "site: --text-encoder int8-weights": {"text_encoder": "int8-weights"},
            "site: --text-encoder int8-weights --denoiser int8": {"text_encoder": "int8-weights",
                                                                 "denoiser": "int8"}}
SECONDS, NFE = 4.0, 5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--only", nargs="*", default=None,
                        help="the variants to run (their position in VARIANTS, from 0; the torch "
                        "pipeline is -1); default: all")
    parser.add_argument("--two-actions", action="store_true",
                        help="the two-action prompts as the page makes them, split or whole")
    parser.add_argument("--hand-written", action="store_true",
                        help="the hand-written paraphrase sets, at the default length")
    parser.add_argument("--captions", type=Path, default=None,
                        help="a procedural benchmark: its test captions, as the page makes them")
    args = parser.parse_args()
    if args.two_actions:
        return two_actions(args.seeds)
    if args.captions is not None:
        return captions(args.captions, args.seeds)
    if args.hand_written:
        return hand_written(args.seeds)
    chosen = set(range(-1, len(VARIANTS)) if args.only is None else map(int, args.only))
    torch.set_num_threads(1)
    items = json.loads(PROMPTS.read_text(encoding="utf-8"))["paraphrases"]
    pipe = mlct.load()
    frames = round(SECONDS * pipe.skeleton.fps)
    print(f"{len(items)} paraphrases x {args.seeds} seeds, {SECONDS} s, {NFE} NFE")
    tally = Tally()
    for seed in range(args.seeds if -1 in chosen else 0):
        out = pipe.generate([p["text"] for p in items], seconds=SECONDS, nfe=NFE,
                            seed=seed * 100_000, split_actions=False, candidates=1)
        for item, motion in zip(items, out):
            label = prompt_label(item["actions"], SECONDS)
            tally.add(label, evaluate_label(motion.joints, label))
    if -1 in chosen:
        report("torch pipeline (the bundled model)", tally)
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, options) in enumerate(VARIANTS.items()):
            if i not in chosen:
                continue
            generator = load_site_reference(export_site("bundled", Path(tmp) / f"s{i}",
                                                        **options), threads=1)
            tally = Tally()
            for seed in range(args.seeds):
                for k, item in enumerate(items):
                    # one sample, the whole prompt: the variants compared as they were first
                    # (docs/web.md's table), the torch row above made the same way
                    _, joints = generate_with_portable_noise(generator, item["text"], frames,
                                                             NFE, seed * 1000 + k,
                                                             split_actions=False, candidates=1)
                    label = prompt_label(item["actions"], SECONDS)
                    tally.add(label, evaluate_label(joints, label))
            report(name, tally)


def makers(tmp: Path, pipe) -> dict[str, Callable[[str, int, int], np.ndarray]]:
    """(text, frames, seed) -> planted joints, per way of making a motion: the page before this
    change (its old default int8 text encoder, the whole prompt, one sample), the page now (the
    int8-weights text encoder, prompts split as generate() splits them) at one sample and at the
    model's best of 8, and the torch pipeline at both."""
    before = load_site_reference(export_site("bundled", tmp / "int8", text_encoder="int8"),
                                 threads=1)
    site = load_site_reference(export_site("bundled", tmp / "default"), threads=1)
    return {
        "page before": lambda text, frames, seed: generate_with_portable_noise(
            before, text, frames, NFE, seed, split_actions=False, candidates=1)[1],
        "page, 1 sample": lambda text, frames, seed: generate_with_portable_noise(
            site, text, frames, NFE, seed, candidates=1)[1],
        "page, best of 8": lambda text, frames, seed: generate_with_portable_noise(
            site, text, frames, NFE, seed)[1],
        "torch, 1 sample": lambda text, frames, seed: pipe.generate(
            text, lengths=frames, nfe=NFE, seed=seed, candidates=1)[0].joints,
        "torch, best of 8": lambda text, frames, seed: pipe.generate(
            text, lengths=frames, nfe=NFE, seed=seed)[0].joints}


def two_actions(seeds: int, seconds: float = 7.0) -> None:
    torch.set_num_threads(1)
    items = json.loads(PROMPTS.read_text(encoding="utf-8"))["two_actions"]
    pipe = mlct.load()
    frames = round(seconds * pipe.skeleton.fps)
    print(f"{len(items)} two-action prompts x {seeds} seeds, {seconds} s, {NFE} NFE")
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in makers(Path(tmp), pipe).items():
            tallies = [Tally(), Tally()]
            for seed in range(seeds):
                for k, item in enumerate(items):
                    joints = make(item["text"], frames, seed * 1000 + k)
                    for tally, halves in zip(tallies, (False, True)):
                        tally.add(*judge_prompt(joints, item["actions"],
                                                len(joints) / pipe.skeleton.fps, halves=halves))
            print(f"{name}: in order {tallies[0].summary()['overall']:.3f}, halves "
                  f"{tallies[1].summary()['overall']:.3f} ({tallies[0].summary()['motions']} "
                  f"motions)", flush=True)


def hand_written(seeds: int) -> None:
    torch.set_num_threads(1)
    sets = {"seen paraphrases": json.loads(PROMPTS.read_text(encoding="utf-8"))["paraphrases"],
            "held-out": json.loads(HELDOUT.read_text(encoding="utf-8"))["paraphrases"],
            "held-out 2": json.loads(HELDOUT2.read_text(encoding="utf-8"))["paraphrases"]}
    pipe = mlct.load()
    print(f"hand-written sets ({', '.join(f'{k}: {len(v)}' for k, v in sets.items())}) x "
          f"{seeds} seeds, the default length, {NFE} NFE")
    columns: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        ways = makers(Path(tmp), pipe)
        # no length asked (frames None): each way's default, the same rule in the page and the
        # CLI; the page before had a 4-s slider
        old_page = ways["page before"]
        ways["page before"] = lambda text, frames, seed: old_page(
            text, round(4.0 * pipe.skeleton.fps), seed)
        for title, make in ways.items():
            row = []
            for name, items in sets.items():
                tally = Tally()
                for seed in range(seeds):
                    for k, item in enumerate(items):
                        joints = make(item["text"], None, seed * 1000 + k)
                        tally.add(*judge_prompt(joints, item["actions"],
                                                len(joints) / pipe.skeleton.fps))
                row.append(f"{name} {tally.summary()['overall']:.3f} (side "
                           f"{tally.summary()['named_side']:.3f})")
            print(f"{title}: {', '.join(row)}", flush=True)


def captions(data: Path, seeds: int) -> None:
    from mlct.data.labels import read_labels
    from mlct.data.layout import DatasetLayout

    torch.set_num_threads(1)
    layout = DatasetLayout.existing(data)
    labels = read_labels(data)
    names = [n for n in layout.read_split("test") if n in labels]
    texts = [layout.read_texts(n)[0].caption for n in names]
    lengths = [min(len(layout.load_features(n)), MAX_FRAMES) for n in names]
    pipe = mlct.load()
    print(f"{len(names)} test captions of {data} x {seeds} seeds, their own lengths, {NFE} NFE")
    columns = {}
    with tempfile.TemporaryDirectory() as tmp:
        for title, make in makers(Path(tmp), pipe).items():
            tally = Tally()
            for seed in range(seeds):
                for k, name in enumerate(names):
                    joints = make(texts[k], lengths[k], seed * 1000 + k)
                    tally.add(labels[name], evaluate_label(joints, labels[name]))
            columns[title] = tally.summary()
            print(f"{title}: {columns[title]['overall']:.3f}", flush=True)
    print_table("read-out pass rates of the test captions", columns)


def report(name: str, tally: Tally) -> None:
    summary = tally.summary()
    print(f"{name}: pass rate {summary['overall']:.3f} ({summary['motions']} motions), named "
          f"side {summary['named_side']:.3f} ({summary['named_side_n']})", flush=True)


if __name__ == "__main__":
    main()
