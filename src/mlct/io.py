"""Atomic file writing: a reader never sees a half-written file.

Everything mlct writes (datasets, checkpoints, renders, exports) goes through `atomic_path`:
write to a temporary name in the same directory, then `os.replace` it onto the final name.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator

import numpy as np

from mlct.errors import MlctError

if TYPE_CHECKING:
    import torch


def _fsync(path: Path) -> None:
    """Flush a file's or a directory's entries to the disk: a rename is atomic against a crash
    of the process, but only durable against power loss once both sides are synced."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return  # e.g. a directory that cannot be opened on this platform
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems (and Windows directories) refuse: best effort
    finally:
        os.close(fd)


def _make_parents(directory: Path) -> list[Path]:
    """mkdir -p directory; returns the directories it created, deepest first, so that a failed
    write can remove them again (a failed command leaves no empty folders behind)."""
    created = []
    for folder in (directory, *directory.parents):
        if folder.exists():
            if not folder.is_dir():  # else mkdir's "File exists: afile" names no problem
                raise MlctError(f"cannot write in {directory}: {folder} is not a directory")
            break
        created.append(folder)
    directory.mkdir(parents=True, exist_ok=True)
    return created


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:  # deepest first; stop at one that something else has filled
        try:
            folder.rmdir()
        except OSError:
            return


def readable_by_umask(path: Path) -> None:
    """Give a file written private (0600: mkstemp, safetensors) an ordinary file's permissions,
    0666 less the user's umask."""
    umask = os.umask(0)
    os.umask(umask)
    path.chmod(0o666 & ~umask)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success it replaces `path`, on error it is removed.

    `suffix` defaults to the final suffix, so libraries that pick a format from the extension
    (matplotlib, numpy) behave as they would on the final name.
    """
    path = Path(path)
    created = _make_parents(path.parent)
    # The temporary name starts with a dot and keeps the final extension: dataset readers skip
    # dot-files, and format-sniffing writers see the right extension.
    if suffix is None:
        suffix = ".tmp" + path.suffix
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    readable_by_umask(tmp_path)  # mkstemp makes the file private (0600)
    try:
        yield tmp_path
        _fsync(tmp_path)
        os.replace(tmp_path, path)
        _fsync(path.parent)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        _remove_empty(created)
        raise


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike) -> Iterator[Path]:
    """Yield an empty hidden directory beside `path`; on success it replaces `path` (an old
    directory is removed only then), on error it is removed and `path` is untouched."""
    path = Path(path)
    created = _make_parents(path.parent)
    work = Path(tempfile.mkdtemp(prefix=f".{path.name}.partial-", dir=path.parent))
    try:
        yield work
        work.chmod(0o755)  # mkdtemp makes it private; the result is an ordinary directory
        for item in [*work.rglob("*"), work]:  # on disk before the rename makes it visible
            _fsync(item)
        if path.exists():
            trash = Path(tempfile.mkdtemp(prefix=f".{path.name}.old-", dir=path.parent))
            os.replace(path, trash / path.name)
            shutil.rmtree(trash)
        os.replace(work, path)
        _fsync(path.parent)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        _remove_empty(created)
        raise


def link_or_copy(src: str | os.PathLike, dst: str | os.PathLike) -> None:
    """A hard link of `src` at `dst` (a dataset copy shares its motions), else a copy: another
    file system, or links not allowed."""
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def copy_dataset(src: str | os.PathLike, dst: str | os.PathLike, skip: set[str]) -> None:
    """A dataset's files into the existing folder `dst`, but the top-level names in `skip`:
    the files of its folders (motions, texts) hard-linked where possible, top files copied, so
    that a derived dataset writes only what it changes."""
    for item in sorted(Path(src).iterdir()):
        if item.name in skip:
            continue
        if item.is_dir():
            (Path(dst) / item.name).mkdir()
            for f in item.iterdir():
                link_or_copy(f, Path(dst) / item.name / f.name)
        else:
            shutil.copy2(item, Path(dst) / item.name)


def save_npy(path: str | os.PathLike, array: np.ndarray) -> None:
    """np.save, atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.save(f, array)


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write UTF-8 text atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write bytes atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def check_writable_dir(directory: str | os.PathLike) -> Path:
    """MlctError in one line, before any work, unless files can be written in directory: it is
    a directory, or its nearest existing ancestor is, and we may write there. Creates nothing."""
    directory = Path(directory)
    existing = directory
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise MlctError(f"cannot write in {directory}: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise MlctError(f"cannot write in {directory}: {existing} is not writable")
    return directory


def read_format_json(path: str | os.PathLike, format_name: str, version: int,
                     what: str) -> dict[str, Any]:
    """A JSON file that names its format and version (model, evaluator, classifier
    descriptions), checked; a one-line MlctError naming `what` the file should describe."""
    path = Path(path)
    if not path.is_file():
        raise MlctError(f"{path.parent}: no {path.name} (not {what})")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:  # UnicodeDecodeError is a ValueError
        raise MlctError(f"{path}: unreadable, not valid JSON ({error})") from None
    if not isinstance(meta, dict) or meta.get("format") != format_name:
        raise MlctError(f"{path}: not {what} (format is not {format_name!r})")
    if meta.get("version") != version:
        raise MlctError(f"{path}: version {meta.get('version')!r}, this mlct reads {version}")
    return meta

# Tensor-dict helpers: a module's state_dict inside a checkpoint or bundle lives under a prefix.
def prefixed(prefix: str, state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """A module's state_dict under `prefix.` (the inverse of strip_prefix)."""
    return {f"{prefix}.{k}": v for k, v in state.items()}


def strip_prefix(tensors: dict[str, torch.Tensor], prefix: str) -> dict[str, torch.Tensor]:
    """The tensors under `prefix.`, with the prefix removed (a module's state_dict)."""
    head = prefix + "."
    return {k[len(head):]: v for k, v in tensors.items() if k.startswith(head)}
