"""`mlct data merge`: one dataset in the standard layout made of several.

    DST/ = every source's motions, texts and (when all have them) labels; the first source's
           names kept, the k-th source's (k >= 2) prefixed `d{k}_` so that no two collide;
           each split the sources' lists of it one after another (duplicates kept, so an
           oversampled split stays oversampled); Mean.npy / Std.npy the first source's.

Why: a stage can see more distinct motions than one benchmark holds (a second seed of `mlct data
synth`, or your own imported capture beside the benchmark so that fine-tuning does not forget
it). The normalization is the first source's on purpose: a model trained on the first continues
on the merge with the statistics it was trained with (run `mlct data stats DST` to refit them
for a model trained from scratch). Files are hard-linked where the file system allows.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from mlct.data.labels import LABELS_FILE, SYNTH_META, read_labels, read_synth_meta
from mlct.data.oversample import repeating_splits
from mlct.data.layout import (FEATURES_DIR, JOINTS_DIR, OPTIONAL_SPLITS, PROVENANCE_FILE, SPLITS,
                              TEXTS_DIR, read_provenance, read_split)
from mlct.errors import MlctError
from mlct.io import atomic_dir, link_or_copy, write_text

STATS_FILES = ("Mean.npy", "Std.npy")
MOTION_DIRS = (FEATURES_DIR, JOINTS_DIR, TEXTS_DIR)
KEPT_META = ("generator", "version", "skeleton", "fps")  # of the first source's synth.json


def source_prefix(index: int) -> str:
    """The name prefix of the index-th source (0-based): none for the first, then d2_, d3_ ...
    ("M" would mark a mirrored copy in HumanML3D's layout, so no prefix starts with it)."""
    return "" if index == 0 else f"d{index + 1}_"


def _feature_width(src: Path) -> int:
    """The feature width of a dataset, from its Mean.npy (every loader normalizes with it)."""
    path = src / "Mean.npy"
    if not path.is_file():
        raise MlctError(f"{src}: no Mean.npy (run `mlct data stats {src}` first)")
    return int(np.load(path).shape[-1])


def _check_sources(sources: list[Path], out: Path, overwrite: bool) -> None:
    if len(sources) < 2:
        raise MlctError("merge needs two or more source datasets")
    resolved = [s.resolve() for s in sources]
    if len(set(resolved)) != len(resolved):
        raise MlctError("a source dataset is named twice")
    if out.resolve() in resolved:
        raise MlctError("--out must differ from every source (they are read, not edited)")
    if out.exists() and not overwrite:
        raise MlctError(f"{out} exists; pass --overwrite to replace it")
    for src in sources:
        if not (src / FEATURES_DIR).is_dir():
            raise MlctError(f"{src}: not a dataset in the standard layout (no {FEATURES_DIR}/)")
    widths = {src: _feature_width(src) for src in sources}
    if len(set(widths.values())) != 1:
        listed = ", ".join(f"{src} {width}" for src, width in widths.items())
        raise MlctError(f"the sources have different feature widths ({listed}): one skeleton "
                        f"per dataset")


def _link_motions(src: Path, work: Path, prefix: str) -> int:
    """Hard-link one source's per-motion files into `work` under prefixed names."""
    count = 0
    for folder in MOTION_DIRS:
        if not (src / folder).is_dir():
            continue
        for f in sorted((src / folder).iterdir()):
            target = work / folder / f"{prefix}{f.name}"
            if target.exists():  # e.g. a first source that already has a d2_ name
                raise MlctError(f"two sources give {folder}/{target.name}; rename one "
                                f"source's motions first")
            link_or_copy(f, target)
            count += folder == FEATURES_DIR
    return count


def _merged_labels(sources: list[Path]) -> list[dict[str, Any]] | None:
    """Every source's label records, renamed; None when a source has no labels.jsonl."""
    if not all((src / LABELS_FILE).is_file() for src in sources):
        return None
    records = []
    for index, src in enumerate(sources):
        for name, record in read_labels(src).items():
            records.append({**record, "name": source_prefix(index) + name})
    return records


# What a source without provenance.jsonl is taken to be: a procedural benchmark made by
# `mlct data synth` (its synth.json says so) is this project's own data; anything else unknown.
PROCEDURAL = {"corpus": "procedural", "source": "mlct data synth", "license": "MIT",
              "commercial_use": True}
UNKNOWN = {"corpus": "unknown", "license": "unknown", "commercial_use": None}


def _merged_provenance(sources: list[Path], metas: list[dict[str, Any]]
                       ) -> list[dict[str, Any]] | None:
    """Every motion's provenance record, renamed; None when no source has provenance.jsonl
    (a merge of procedural benchmarks alone needs none)."""
    if not any((src / PROVENANCE_FILE).is_file() for src in sources):
        return None
    records = []
    for index, (src, meta) in enumerate(zip(sources, metas)):
        prefix = source_prefix(index)
        if (src / PROVENANCE_FILE).is_file():
            records += [{**r, "name": prefix + r["name"]} for r in read_provenance(src)]
            continue
        default = PROCEDURAL if meta.get("generator") else UNKNOWN
        for f in sorted((src / FEATURES_DIR).iterdir()):
            records.append({"name": prefix + f.stem, **default})
    return records


def merge_datasets(sources: list[str | os.PathLike], out: str | os.PathLike,
                   overwrite: bool = False) -> dict[str, Any]:
    """Write DST (module docstring); returns {"motions": per source, "splits": sizes}."""
    sources, out = [Path(s) for s in sources], Path(out)
    _check_sources(sources, out, overwrite)
    metas = [read_synth_meta(src) for src in sources]
    splits: dict[str, list[str]] = {}
    motions = []
    with atomic_dir(out) as work:
        for folder in MOTION_DIRS:
            (work / folder).mkdir()
        for index, src in enumerate(sources):
            prefix = source_prefix(index)
            motions.append(_link_motions(src, work, prefix))
            for split in SPLITS + OPTIONAL_SPLITS:
                if (src / f"{split}.txt").is_file():
                    names = read_split(src / f"{split}.txt")
                    splits.setdefault(split, []).extend(prefix + n for n in names)
        for split, names in splits.items():
            write_text(work / f"{split}.txt", "\n".join(names) + "\n")
        for name in STATS_FILES:
            if (sources[0] / name).is_file():
                link_or_copy(sources[0] / name, work / name)
        provenance = _merged_provenance(sources, metas)
        if provenance is not None:
            write_text(work / PROVENANCE_FILE,
                       "".join(json.dumps(r, sort_keys=True) + "\n" for r in provenance))
        labels = _merged_labels(sources)
        if labels is not None:
            write_text(work / LABELS_FILE, "".join(json.dumps(r) + "\n" for r in labels))
        meta = {"merged": [{"from": str(src), "prefix": source_prefix(i), "motions": n}
                           for i, (src, n) in enumerate(zip(sources, motions))],
                "normalization_from": str(sources[0]),
                "splits": {split: len(names) for split, names in splits.items()},
                # an oversampled source's repeats are kept, and `mlct data check` told so
                "repeating_splits": sorted(set().union(*(repeating_splits(m) for m in metas)))}
        # the generator, skeleton and fps of the first, for readers
        meta = {**{k: metas[0][k] for k in KEPT_META if k in metas[0]}, **meta}
        write_text(work / SYNTH_META, json.dumps(meta, indent=2) + "\n")
    return {"motions": motions, "splits": {k: len(v) for k, v in splits.items()}}
