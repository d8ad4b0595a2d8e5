from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from mlct.io import atomic_dir, atomic_path, write_text


def test_atomic_file_is_an_ordinary_file_under_the_umask(tmp_path: Path) -> None:
    target = tmp_path / "a.txt"
    write_text(target, "hello")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    assert target.read_text() == "hello"


def test_failed_atomic_write_keeps_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "a.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_atomic_dir_replaces_only_on_success(tmp_path: Path) -> None:
    target = tmp_path / "d"
    with atomic_dir(target) as work:
        (work / "x").write_text("1")
    with pytest.raises(RuntimeError):
        with atomic_dir(target) as work:
            (work / "x").write_text("2")
            raise RuntimeError("boom")
    assert (target / "x").read_text() == "1"
    assert stat.S_IMODE(target.stat().st_mode) == 0o755
