"""`mlct data rephrase`: a copy of a procedural benchmark whose training captions say each motion
in more ways (the everyday vocabulary, data/synth/everyday.py, or the short one of bare verbs,
data/synth/short.py).

    DST/ = SRC/ with texts/NAME.txt of every motion in `splits` holding its captions plus
           `per_motion` new ones; every other file the same (motions hard-linked where the file
           system allows, else copied). synth.json records what was added ("rephrased", a list
           when SRC was itself rephrased).

The motions, labels, splits and normalization are SRC's, so an autoencoder or a stage-2 model
trained on SRC reads DST unchanged and a continuation (`mlct train cm --init MODEL --data DST`)
sees only new words. Test and validation captions stay as they are unless asked.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from mlct.data.captions import format_text_line, tag_caption
from mlct.data.labels import read_labels, read_synth_meta
from mlct.data.layout import read_split
from mlct.data.oversample import families_of
from mlct.data.synth.everyday import EVERYDAY
from mlct.data.synth.colloquial import COLLOQUIAL, CONTEXT
from mlct.data.synth.short import SHORT
from mlct.data.synth.text import FAMILIES, Vocabulary, describe
from mlct.errors import MlctError
from mlct.io import atomic_dir, copy_dataset, write_text


VOCABULARIES: dict[str, Vocabulary] = {"everyday": EVERYDAY, "short": SHORT,
                                        "colloquial": COLLOQUIAL, "context": CONTEXT}


def everyday_captions(record: dict[str, Any], rng: np.random.Generator, count: int,
                      vocabulary: str = "everyday") -> list[str]:
    """`count` distinct captions of one labels.jsonl record in a VOCABULARIES one."""
    actions = [SimpleNamespace(family=a["family"], params=a["params"]) for a in record["actions"]]
    concurrent = record.get("concurrent")
    with_ = None if concurrent is None else SimpleNamespace(family=concurrent["family"],
                                                            params=concurrent["params"])
    return describe(actions, rng, count, with_, vocabulary=VOCABULARIES[vocabulary])


def rephrase_dataset(src: str | os.PathLike, out: str | os.PathLike, per_motion: int = 3,
                     splits: tuple[str, ...] = ("train",), seed: int = 0,
                     overwrite: bool = False, vocabulary: str = "everyday",
                     skip_families: tuple[str, ...] = ()) -> dict[str, Any]:
    """Write DST (module docstring); returns {"motions": rephrased, "captions": added}.

    A motion with an action (or a concurrent one) of `skip_families` keeps its captions as they
    are, so a vocabulary can be added to some families only (the controls of docs/training.md, used
    it)."""
    src, out = Path(src), Path(out)
    if vocabulary not in VOCABULARIES:
        raise MlctError(f"--vocabulary must be one of {', '.join(VOCABULARIES)}, "
                        f"got {vocabulary!r}")
    unknown = sorted(set(skip_families) - set(FAMILIES))
    if unknown:
        raise MlctError(f"--skip-families: unknown family {unknown[0]!r} "
                        f"(families: {', '.join(FAMILIES)})")
    if per_motion < 1:
        raise MlctError(f"--per-motion must be >= 1, got {per_motion}")
    if out.resolve() == src.resolve():
        raise MlctError("--out must differ from the source dataset (it is copied, not edited)")
    if out.exists() and not overwrite:
        raise MlctError(f"{out} exists; pass --overwrite to replace it")
    labels = read_labels(src)
    chosen: set[str] = set()
    for split in splits:
        if not (src / f"{split}.txt").is_file():
            raise MlctError(f"{src}: no split '{split}' ({split}.txt)")
        chosen.update(read_split(src / f"{split}.txt"))
    missing = sorted(chosen - set(labels))
    if missing:
        raise MlctError(f"{src}: {len(missing)} motions of {', '.join(splits)} have no label "
                        f"(first: {missing[0]})")
    skip = set(skip_families)
    chosen = {name for name in chosen if skip.isdisjoint(families_of(labels[name]))}
    rng = np.random.default_rng(seed)
    added = 0
    with atomic_dir(out) as work:
        copy_dataset(src, work, skip={"texts", "synth.json"})
        (work / "texts").mkdir()
        for path in sorted((src / "texts").iterdir()):
            text = path.read_text(encoding="utf-8")
            name = path.stem
            if name in chosen:
                lines = [format_text_line(c, tag_caption(c))
                         for c in everyday_captions(labels[name], rng, per_motion, vocabulary)]
                text = text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"
                added += len(lines)
            (work / "texts" / path.name).write_text(text, encoding="utf-8")
        meta = read_synth_meta(src)
        step = {"from": str(src), "vocabulary": vocabulary, "per_motion": per_motion,
                "splits": list(splits), "seed": seed, "captions_added": added}
        if skip_families:
            step["skip_families"] = sorted(skip_families)
        before = meta.get("rephrased")
        meta["rephrased"] = step if before is None else [
            *(before if isinstance(before, list) else [before]), step]
        write_text(work / "synth.json", json.dumps(meta, indent=2) + "\n")
    return {"motions": len(chosen), "captions": added}
