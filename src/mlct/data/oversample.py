"""`mlct data oversample`: a copy of a labelled dataset whose training split lists the motions of
some action families more than once, so that a stage sees them more often.

    DST/ = SRC/ with SPLIT.txt listing each chosen motion `times` times (the split reader keeps
           duplicates, data/layout.py), every other file the same (hard-linked where the file
           system allows, else copied); synth.json (when SRC has one) records what was chosen.

Why: stage 2 learned the actions whose checks need several cycles (claps and waves counted, a
turn's whole angle) slowest, and an underfit of a few families is what rebalancing the
batches is for (docs/training.md, "Oversampling the slow families"). The motions, labels and
normalization are SRC's, so a model trained on SRC continues on DST unchanged.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from mlct.data.labels import SYNTH_META, read_labels, read_synth_meta
from mlct.data.layout import read_split
from mlct.errors import MlctError
from mlct.io import atomic_dir, copy_dataset, write_text


def repeating_splits(meta: dict[str, Any]) -> set[str]:
    """The splits a dataset's synth.json says list motions more than once on purpose: the one
    `oversample` rebalanced, and those of the sources a `merge` joined."""
    splits = set(meta.get("repeating_splits", []))
    if isinstance(meta.get("oversampled"), dict) and meta["oversampled"].get("split"):
        splits.add(meta["oversampled"]["split"])
    return splits


def families_of(record: dict[str, Any]) -> list[str]:
    """The families a labels.jsonl record shows, in time order, a concurrent one last."""
    families = [action["family"] for action in record["actions"]]
    if record.get("concurrent"):
        families.append(record["concurrent"]["family"])
    return families


def chosen_motions(labels: dict[str, dict[str, Any]], names: list[str], families: set[str],
                   single_only: bool) -> list[str]:
    """The motions of `names` that show one of `families` (alone, when single_only)."""
    chosen = []
    for name in names:
        shown = families_of(labels[name])
        if single_only and len(shown) != 1:
            continue
        if families.intersection(shown):
            chosen.append(name)
    return chosen


def oversample_dataset(src: str | os.PathLike, out: str | os.PathLike, families: list[str],
                       times: int = 3, split: str = "train", single_only: bool = True,
                       overwrite: bool = False) -> dict[str, Any]:
    """Write DST (module docstring); returns {"chosen": motions repeated, "items": split size}."""
    src, out = Path(src), Path(out)
    if times < 2:
        raise MlctError(f"--times must be >= 2 (1 would copy the dataset unchanged), got {times}")
    if not families:
        raise MlctError("--families names no family")
    if out.resolve() == src.resolve():
        raise MlctError("--out must differ from the source dataset (it is copied, not edited)")
    if out.exists() and not overwrite:
        raise MlctError(f"{out} exists; pass --overwrite to replace it")
    split_file = src / f"{split}.txt"
    if not split_file.is_file():
        raise MlctError(f"{src}: no split '{split}' ({split}.txt)")
    labels = read_labels(src)
    known = {family for record in labels.values() for family in families_of(record)}
    unknown = sorted(set(families) - known)
    if unknown:
        raise MlctError(f"{src}: no motion shows {', '.join(unknown)} (families here: "
                        f"{', '.join(sorted(known))})")
    names = read_split(split_file)
    missing = sorted(set(names) - set(labels))
    if missing:
        raise MlctError(f"{src}: {len(missing)} motions of {split} have no label "
                        f"(first: {missing[0]})")
    chosen = chosen_motions(labels, names, set(families), single_only)
    if not chosen:
        raise MlctError(f"{src}: no motion of {split} shows {', '.join(families)}"
                        + (" alone" if single_only else ""))
    listed = names + chosen * (times - 1)
    with atomic_dir(out) as work:
        copy_dataset(src, work, skip={split_file.name, "synth.json"})
        write_text(work / split_file.name, "\n".join(listed) + "\n")
        if (src / SYNTH_META).is_file():
            meta = read_synth_meta(src)
            meta["oversampled"] = {"from": str(src), "split": split, "families": list(families),
                                   "times": times, "single_only": single_only,
                                   "motions": len(chosen)}
            write_text(work / "synth.json", json.dumps(meta, indent=2) + "\n")
    return {"chosen": len(chosen), "items": len(listed)}
