"""labels.jsonl: the procedural benchmark's ground truth per motion (its actions with their
parameters and time windows, a concurrent action, the captions), one JSON record a line.
`mlct data synth` writes it; the action classifier, the read-out benchmark, `mlct data
rephrase` and the critic's trainer read it here."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from mlct.errors import MlctError

LABELS_FILE = "labels.jsonl"
SYNTH_META = "synth.json"  # how a benchmark was made: seed, version, what later steps changed


def read_synth_meta(data_dir: str | os.PathLike) -> dict[str, Any]:
    """synth.json of a dataset ({} when it has none: it is provenance, not required); an
    unreadable one raises MlctError naming it."""
    path = Path(data_dir) / SYNTH_META
    if not path.is_file():
        return {}
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise MlctError(f"{path}: not readable JSON ({error})") from None
    if not isinstance(meta, dict):
        raise MlctError(f"{path}: not a JSON object")
    return meta


def read_labels(data_dir: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """labels.jsonl of a procedural benchmark, by motion name."""
    path = Path(data_dir) / LABELS_FILE
    if not path.is_file():
        raise MlctError(f"{path}: missing; only procedural benchmarks (`mlct data synth`) carry "
                        f"action labels")
    records = {}
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if line.strip():
            try:
                record = json.loads(line)
                records[record["name"]] = record
            except (ValueError, KeyError, TypeError) as error:
                raise MlctError(f"{path}:{number}: not a label record ({error!r})") from None
    return records
