"""Checkpoints: weights in safetensors (config and step as metadata), training state beside them.

A checkpoint is a directory `step-00001000/` holding `model.safetensors` and `state.pt`
(optimizer, LR schedule, RNG states). It is written under a temporary name and renamed into
place, and `latest` (a one-line file, itself replaced atomically) names the newest one, so a
kill at any moment leaves the previous checkpoint intact and readable.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, safe_open, save_file

from mlct.errors import MlctError, first_line
from mlct.io import atomic_dir, strip_prefix, write_text

FORMAT = "mlct-checkpoint"
VERSION = "1"
WEIGHTS = "model.safetensors"
STATE = "state.pt"


@dataclass
class Checkpoint:
    """What a checkpoint holds, read back."""

    path: Path
    tensors: dict[str, torch.Tensor]  # "ae.*", "denoiser.*", "ema.*" ...
    meta: dict[str, Any]  # stage, step, config (dict), feature_dim, text encoder ...
    state: dict[str, Any] | None  # optimizer / scheduler / rng; None when not loaded

    def module_state(self, prefix: str) -> dict[str, torch.Tensor]:
        """The tensors under `prefix.` with the prefix removed (a module's state_dict)."""
        found = strip_prefix(self.tensors, prefix)
        if not found:
            raise MlctError(f"{self.path}: holds no '{prefix}' weights")
        return found




def save_weights(path: Path, tensors: dict[str, torch.Tensor], meta: dict[str, Any]) -> None:
    """safetensors file with JSON-encoded metadata values (safetensors stores strings only)."""
    flat = {k: v.detach().to("cpu").contiguous().clone() for k, v in tensors.items()}
    header = {"format": FORMAT, "version": VERSION}
    header.update({k: json.dumps(v) for k, v in meta.items()})
    save_file(flat, str(path), metadata=header)


def read_weights(path: str | os.PathLike) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """Tensors and metadata of an mlct safetensors file; one-line MlctError when it is not one."""
    path = Path(path)
    if not path.is_file():
        raise MlctError(f"{path}: no such checkpoint file")
    try:
        with safe_open(str(path), framework="pt") as handle:
            header = handle.metadata() or {}
        tensors = load_file(str(path))
    except (SafetensorError, OSError, ValueError, RuntimeError) as err:
        raise MlctError(f"{path}: not a readable safetensors file "
                        f"({first_line(err)})") from None
    if header.get("format") != FORMAT:
        raise MlctError(f"{path}: not an mlct checkpoint (no '{FORMAT}' metadata)")
    if header.get("version") != VERSION:
        raise MlctError(f"{path}: checkpoint version {header.get('version')} is not supported "
                        f"(this mlct reads version {VERSION})")
    meta = {k: json.loads(v) for k, v in header.items() if k not in ("format", "version")}
    return tensors, meta


def save_checkpoint(directory: str | os.PathLike, step: int,
                    tensors: dict[str, torch.Tensor], meta: dict[str, Any],
                    state: dict[str, Any], keep: int = 2) -> Path:
    """Write checkpoint `step` under `directory` atomically, point `latest` at it, prune old."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    remove_partial_writes(directory)
    name = f"step-{step:08d}"
    final = directory / name
    with atomic_dir(final) as tmp:  # re-saving a step (e.g. the last one) replaces it
        save_weights(tmp / WEIGHTS, tensors, {**meta, "step": step})
        torch.save(state, tmp / STATE)
    write_text(directory / "latest", name + "\n")
    kept = sorted(p for p in directory.glob("step-*") if p.is_dir())
    for old in kept[:-keep] if keep > 0 else []:
        shutil.rmtree(old, ignore_errors=True)
    return final


CHECKPOINT_NAME = re.compile(r"step-\d{8}")


def remove_partial_writes(directory: str | os.PathLike) -> list[Path]:
    """Remove what a killed checkpoint write left (atomic_dir's hidden .step-*.partial-* and
    .step-*.old-* folders); returns them. Safe: no finished checkpoint is ever named so."""
    removed = []
    for leftover in Path(directory).glob(".step-*"):
        if leftover.is_dir() and (".partial-" in leftover.name or ".old-" in leftover.name):
            shutil.rmtree(leftover, ignore_errors=True)
            removed.append(leftover)
    return removed


def intact_checkpoints(directory: str | os.PathLike) -> list[Path]:
    """The step-N folders that hold weights, newest first."""
    found = [p for p in Path(directory).glob("step-*")
             if CHECKPOINT_NAME.fullmatch(p.name) and (p / WEIGHTS).is_file()]
    return sorted(found, reverse=True)


def latest_checkpoint(directory: str | os.PathLike) -> Path | None:
    """The checkpoint `latest` names, or None when the directory has none yet."""
    pointer = Path(directory) / "latest"
    if not pointer.is_file():
        return None
    # Undecodable bytes are read as U+FFFD: such a name is refused below like any other.
    name = pointer.read_bytes().decode("utf-8", errors="replace").strip()
    if not CHECKPOINT_NAME.fullmatch(name):  # never joined to a path: it could point outside
        raise MlctError(f"{pointer} holds {name[:40]!r}, not a checkpoint name like "
                        f"step-00001000{_intact_hint(directory)}")
    path = Path(directory) / name
    if not (path / WEIGHTS).is_file():
        raise MlctError(f"{pointer} names {name}, which is missing or incomplete"
                        f"{_intact_hint(directory)}")
    return path


def _intact_hint(directory: str | os.PathLike) -> str:
    intact = intact_checkpoints(directory)
    return (f"; the newest intact checkpoint is {intact[0]} (write its name into "
            f"{Path(directory) / 'latest'} to use it)" if intact else "")


def resume_checkpoint(directory: str | os.PathLike) -> tuple[Checkpoint, str | None]:
    """The checkpoint to resume from: `latest`, or when it is broken (missing, unreadable) the
    newest intact one before it, with a one-line note saying so. MlctError when none is."""
    directory = Path(directory)
    try:
        found = latest_checkpoint(directory)
        if found is None:
            raise MlctError(f"{directory}: no checkpoint to resume from")
        return load_checkpoint(found), None
    except MlctError as broken:
        for candidate in intact_checkpoints(directory):
            try:
                checkpoint = load_checkpoint(candidate)
            except MlctError:
                continue
            return checkpoint, (f"latest checkpoint unusable ({broken}); resuming from "
                                f"{candidate.name}")
        raise


def load_checkpoint(path: str | os.PathLike, with_state: bool = True) -> Checkpoint:
    """Read a checkpoint directory (or a bare model.safetensors file)."""
    path = Path(path)
    weights = path / WEIGHTS if path.is_dir() else path
    tensors, meta = read_weights(weights)
    state = None
    if with_state:
        state_path = weights.parent / STATE
        if not state_path.is_file():
            raise MlctError(f"{state_path}: missing (needed to resume training)")
        try:
            state = torch.load(state_path, map_location="cpu", weights_only=True)
        except Exception as err:  # torch raises many kinds on a damaged pickle
            raise MlctError(f"{state_path}: unreadable training state "
                            f"({type(err).__name__})") from None
    return Checkpoint(path, tensors, meta, state)
