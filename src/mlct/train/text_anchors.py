"""`mlct train anchors`: a model's text anchors (generate/compose/text_anchors.py) from a dataset's
training captions, written beside its weights.

The anchors are the model's text vectors of one split's captions, each caption once; with
labels.jsonl only those of one-action motions, since the pipeline samples a sequence one part at
a time, each with its label's signature (the action, its side, angle and mode, and an arm action
done during it), so that a prompt whose neighbours all say the same is pulled further
(`agreed_pull`). At most `size` of them are kept (a seeded sample; int8 rows, so 12,000 take
4.6 MB).
`near` is measured, not chosen: the `quantile` of the calibration split's captions' cosine with
their nearest anchor, so that unseen captions worded as the benchmark's are left alone.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mlct.data.labels import LABELS_FILE, read_labels
from mlct.data.layout import DatasetLayout
from mlct.errors import MlctError
from mlct.generate.bundle import read_bundle
from mlct.generate.compose.text_anchors import TextAnchors, int8_rows, save_text_anchors

SIZE = 12000
PULL, SPAN, NEIGHBOURS, QUANTILE = 0.5, 0.2, 5, 0.05
AGREED_PULL = 1.0
# What a caption states of its action: its side, angle and mode. Counts, steps and speeds are
# often left unsaid ("a person hops on the left leg" of a three-hop motion), so they are not
# part of the signature: two captions that differ only there say the same thing.
SIGNATURE_KEYS = ("side", "hand", "leg", "angle", "mode")


def _captions_said(data_dir: str | os.PathLike, split: str) -> dict[str, set[tuple] | None]:
    """The split's captions of one-action motions (where labels.jsonl says; a motion without a
    label is kept, nothing says it is not one), each with the signatures of the labels that say
    it (SIGNATURE_KEYS); None for a caption some unlabelled motion says."""
    layout = DatasetLayout.existing(data_dir)
    labels = read_labels(data_dir) if (Path(data_dir) / LABELS_FILE).is_file() else {}
    said: dict[str, set[tuple] | None] = {}
    for name in layout.read_split(split):
        label = labels.get(name)
        signature = None
        if label is not None:
            if len(label.get("actions", [])) != 1:
                continue
            action, concurrent = label["actions"][0], label.get("concurrent") or {}
            signature = (action["family"], *(str(action.get("params", {}).get(k))
                                             for k in SIGNATURE_KEYS),
                         concurrent.get("family"), str(concurrent.get("params", {}).get("hand")))
        for record in layout.read_texts(name):
            caption = record.caption.strip()
            if not caption:
                continue
            known = said.setdefault(caption, set())
            if known is not None:
                said[caption] = None if signature is None else known | {signature}
    return said


def split_captions(data_dir: str | os.PathLike, split: str) -> list[str]:
    """The split's distinct captions, sorted; of one-action motions where labels.jsonl says."""
    return sorted(_captions_said(data_dir, split))


def caption_groups(said: dict[str, set[tuple] | None], captions: list[str]
                   ) -> torch.Tensor | None:
    """(N,) each caption's label signature (_captions_said) as a small integer: -1 where its
    motions' labels say different things or it has none; None when no caption has a label."""
    if not any(said.get(c) for c in captions):
        return None
    ids: dict[tuple, int] = {}
    groups = [ids.setdefault(next(iter(said[c])), len(ids)) if len(said.get(c) or ()) == 1
              else -1 for c in captions]
    return torch.tensor(groups, dtype=torch.long)


def make_text_anchors(data_dir: str | os.PathLike, model_dir: str | os.PathLike,
                      split: str = "train", calibrate: str = "val", size: int = SIZE,
                      pull: float = PULL, span: float = SPAN, neighbours: int = NEIGHBOURS,
                      quantile: float = QUANTILE, seed: int = 0, log: Any = print,
                      agreed_pull: float = AGREED_PULL) -> dict[str, Any]:
    """Make the anchors of the model in `model_dir` from `data_dir` and write them there;
    returns what it measured."""
    if (size < neighbours or not 0.0 < quantile < 1.0 or not 0.0 <= pull <= 1.0
            or not 0.0 <= agreed_pull <= 1.0):
        raise MlctError(f"size must be >= neighbours ({neighbours}), quantile in (0, 1) and "
                        f"pull and agreed pull in [0, 1], got {size}, {quantile}, {pull} and "
                        f"{agreed_pull}")
    from mlct.text import load_text_encoder
    from mlct.text.cache import CachedTextEncoder

    meta, _ = read_bundle(model_dir)
    layout = DatasetLayout.existing(data_dir)
    if calibrate not in layout.splits():
        raise MlctError(f"{data_dir}: no '{calibrate}' split to measure the anchors' reach on")
    said = _captions_said(data_dir, split)
    captions = sorted(said)
    held = split_captions(data_dir, calibrate)
    if len(captions) < neighbours or not held:
        raise MlctError(f"{data_dir}: too few captions ({len(captions)} in '{split}', "
                        f"{len(held)} in '{calibrate}')")
    if len(captions) > size:
        keep = np.random.default_rng(seed).choice(len(captions), size, replace=False)
        captions = [captions[i] for i in sorted(keep)]
    encoder = CachedTextEncoder(load_text_encoder(meta["text_encoder"]))
    vectors = torch.cat([encoder.encode(captions[i:i + 512]).float()
                         for i in range(0, len(captions), 512)])
    rows, scales = int8_rows(vectors)
    stored = rows.float() * scales.float()  # the cosines as the int8 file will give them back
    probe = torch.nn.functional.normalize(encoder.encode(held).float(), dim=1)
    nearest = (probe @ torch.nn.functional.normalize(stored, dim=1).T).amax(dim=1)
    near = float(np.quantile(nearest.numpy(), quantile))
    info = {"data": str(data_dir), "split": split, "captions": len(captions),
            "calibration": {"split": calibrate, "captions": len(held), "quantile": quantile},
            "seed": seed}
    # written once, atomically, when everything is measured: an interrupted run leaves the
    # model's anchors (or their absence) as they were
    groups = caption_groups(said, captions)
    if groups is not None:
        info["groups"] = {"signature": ["family", *SIGNATURE_KEYS, "concurrent", "hand"],
                          "distinct": int(groups.max().item()) + 1,
                          "mixed": int((groups < 0).sum().item())}
    path = save_text_anchors(model_dir, TextAnchors(stored, round(near, 4), span, pull,
                                                    neighbours, info, groups, agreed_pull),
                             meta["text_encoder"])
    log(f"text anchors: {len(captions)} captions of '{split}'; near {near:.3f} (the "
        f"{quantile:.0%} quantile of {len(held)} '{calibrate}' captions' nearest cosine); "
        f"{path.stat().st_size / 1e6:.1f} MB; {path}")
    return {"captions": len(captions), "near": near, "path": str(path)}
