"""The files `mlct generate` reads controls from: --control (the whole JSON schema of
control.py), --path (.json or .csv waypoints), --keyframes (.json), --edit / --prefix (.npy
motions) and --parts."""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path
from typing import Any

from mlct.errors import MlctError, first_line
from mlct.generate.control.schema import Control, control_from_dict
from mlct.motion.skeleton import Skeleton


def read_json(path: str | os.PathLike, what: str) -> Any:
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as error:
        raise MlctError(f"cannot read {what} {path}: {first_line(error)}") from None
    except ValueError as error:
        raise MlctError(f"{path}: not valid JSON ({first_line(error)})") from None


def read_path_file(path: str | os.PathLike) -> list[Any]:
    """Waypoints from .json (a list, or {"path": [...]}) or .csv (columns x, z[, frame][,
    heading]; a header row naming them is optional)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        data = read_json(path, "path")
        return data.get("path", data) if isinstance(data, dict) else data
    if path.suffix.lower() != ".csv":
        raise MlctError(f"--path {path.name}: give a .json or .csv file")
    try:
        rows = [r for r in csv.reader(io.StringIO(path.read_text(encoding="utf-8"))) if r]
    except OSError as error:
        raise MlctError(f"cannot read path {path}: {first_line(error)}") from None
    if not rows:
        raise MlctError(f"{path}: no waypoints")
    header = [c.strip().lower() for c in rows[0]]
    if set(header) <= {"x", "z", "frame", "heading"} and "x" in header:
        names, rows = header, rows[1:]
    else:
        names = ["x", "z", "frame", "heading"][:len(rows[0])]
    out = []
    for number, row in enumerate(rows, start=2 if names is header else 1):
        if len(row) != len(names):
            raise MlctError(f"{path}:{number}: {len(row)} columns, expected {len(names)}")
        try:
            values = {n: float(v) for n, v in zip(names, row)}
        except ValueError:
            raise MlctError(f"{path}:{number}: not a number in {row}") from None
        out.append(values)
    return out


def control_from_files(skeleton: Skeleton, *, control: str | os.PathLike | None = None,
                       path: str | os.PathLike | None = None,
                       keyframes: str | os.PathLike | None = None,
                       edit: str | os.PathLike | None = None, parts: str | None = None,
                       prefix: str | os.PathLike | None = None,
                       frames: int | None = None) -> Control | None:
    """The control of `mlct generate`'s files (--control, --path, --keyframes, --edit, --parts,
    --prefix); None when none is given."""
    found = Control()
    if control is not None:
        found = control_from_dict(read_json(control, "control"), skeleton, str(control), frames)
    data: dict[str, Any] = {}
    if path is not None:
        data["path"] = read_path_file(path)
    if keyframes is not None:
        keys = read_json(keyframes, "keyframes")
        data["keyframes"] = keys.get("keyframes", keys) if isinstance(keys, dict) else keys
    for name, value in (("edit", edit), ("prefix", prefix), ("parts", parts)):
        if value is not None:
            data[name] = value
    if data:
        found = found.merged(control_from_dict(data, skeleton, "command line", frames))
    if found.parts and found.edit is None:  # before the model loads
        raise MlctError("parts name what an edit changes; give the motion to edit (--edit)")
    return None if found.empty else found
