"""Importers of real motion-capture corpora into the standard dataset layout.

`mlct data import --corpus NAME --src DIR --out OUT`: the corpus's clips found in DIR (the
folder its public release unpacks to), captioned from their labels, retargeted and cut by
`import_dataset`, each motion's source and license in provenance.jsonl (base.py). The real
files are never part of this repository; each corpus module says where they are published and
under which license.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from mlct.data.corpora.bandai_namco import BANDAI_NAMCO
from mlct.data.corpora.cmu import CMU
from mlct.data.corpora.cmu_expmap import CMU_EXPMAP
from mlct.data.corpora.base import Corpus, RealClip
from mlct.data.importer import DEFAULT_SPLIT, ImportSummary, import_dataset
from mlct.data.layout import PROVENANCE_FILE, read_provenance, read_split
from mlct.errors import MlctError

CORPORA: dict[str, Corpus] = {c.name: c for c in (BANDAI_NAMCO, CMU, CMU_EXPMAP)}


def corpus(name: str) -> Corpus:
    """The corpus called `name`; MlctError naming the known ones otherwise."""
    if name not in CORPORA:
        raise MlctError(f"unknown corpus {name!r}; known: {', '.join(sorted(CORPORA))}")
    return CORPORA[name]


def import_corpus(name: str, src: str | os.PathLike, out: str | os.PathLike, *,
                  captions_per_clip: int = 4, contents: set[str] | None = None,
                  split: tuple[float, float, float] = DEFAULT_SPLIT, seed: int = 0,
                  overwrite: bool = False, level: bool = True,
                  progress: bool = False) -> ImportSummary:
    """Import corpus `name` from its release folder `src` as a dataset at `out`; `contents`
    keeps only clips of those content labels; `level` as for `import_dataset`."""
    chosen = corpus(name)
    root = Path(src)
    if not root.is_dir():
        raise MlctError(f"{root}: no such directory")
    clips: list[RealClip] = chosen.find(root)
    if contents is not None:
        unknown = contents - {c.labels["content"] for c in clips}
        if unknown:
            raise MlctError(f"no {name} clips of content {', '.join(sorted(unknown))}")
        clips = [c for c in clips if c.labels["content"] in contents]
    rng = np.random.default_rng(seed)
    texts = {c.name: chosen.caption(c.labels, rng, captions_per_clip) for c in clips}
    return import_dataset(
        out, texts, bvh_dir={c.name: c.path for c in clips}, joint_map=chosen.joint_map,
        between=chosen.between, scale=chosen.scale, reader=chosen.read,
        provenance={c.name: chosen.provenance(c, root) for c in clips},
        split=split, seed=seed, overwrite=overwrite, level=level, progress=progress)


def training_data(dataset: str | os.PathLike, split: str = "train") -> dict[str, Any]:
    """What a model trained on `dataset`'s split learnt from, for its config.json's
    `training_data` (generate/bundle.py says a non-commercial license wherever the model is
    loaded): per corpus its motions, source, license and whether it allows commercial use."""
    root = Path(dataset)
    records = read_provenance(root)
    if not records:
        raise MlctError(f"{root / PROVENANCE_FILE}: missing; a dataset made by `mlct data "
                        f"import --corpus` or a merge with one has it")
    names = Counter(read_split(root / f"{split}.txt"))
    corpora: dict[str, dict[str, Any]] = {}
    for record in records:
        if record["name"] not in names:
            continue
        entry = corpora.setdefault(record["corpus"], {
            "corpus": record["corpus"], "source": record.get("source", record["corpus"]),
            "license": record.get("license"), "commercial_use": record.get("commercial_use"),
            "motions": 0})
        entry["motions"] += names[record["name"]]  # an oversampled split counts its repeats
    return {"dataset": str(root), "split": split, "corpora": list(corpora.values())}
