"""On-disk text-embedding cache keyed by (encoder name, caption): each caption is encoded once.

One SQLite file is shared by every process that trains or evaluates (DDP ranks, data-loader
workers). Writes are `INSERT OR IGNORE` (an embedding is a pure function of its key, so whichever
rank wins a race wrote the same vector), and a long busy timeout makes a writer wait for another
instead of failing. The default rollback journal is kept rather than WAL: WAL needs shared memory
and breaks when ranks on several nodes share the cache over a network filesystem.
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
from pathlib import Path
from typing import Iterable, Iterator, Mapping

import numpy as np
import torch
from torch import Tensor

from mlct.errors import MlctError
from mlct.text.base import TextEncoder

CACHE_FILENAME = "text_embeddings.sqlite3"
SCHEMA_VERSION = 1  # stored as PRAGMA user_version
_TIMEOUT_S = 120.0  # how long a process waits for another's write lock
_CHUNK = 500  # rows per query: old SQLite builds allow at most 999 bound variables
_DTYPE = np.dtype("<f4")  # blobs are little-endian float32 on every machine
# Misses are encoded and stored this many at a time: a new dataset of ~100,000 captions takes
# minutes on a CPU, so the work is saved as it goes (an interrupted run keeps what it did, and
# a second process started beside it finds part of it) and a progress bar says where it is.
ENCODE_CHUNK = 4096

_SCHEMA = """
CREATE TABLE IF NOT EXISTS embeddings (
    encoder TEXT NOT NULL,
    text TEXT NOT NULL,
    dim INTEGER NOT NULL,
    vec BLOB NOT NULL,
    PRIMARY KEY (encoder, text)
) WITHOUT ROWID
"""


def default_cache_dir() -> Path:
    """Where mlct caches derived files: $MLCT_CACHE, else ~/.cache/mlct."""
    env = os.environ.get("MLCT_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "mlct"


class EmbeddingCache:
    """A SQLite file of float32 embeddings keyed by (encoder name, text); safe across processes.

    `path` is the database file, or a directory that holds it as `CACHE_FILENAME`: an existing
    directory, a new path without a file extension, or None for `default_cache_dir()`.
    """

    def __init__(self, path: str | os.PathLike | None = None) -> None:
        path = default_cache_dir() if path is None else Path(path).expanduser()
        # A directory, existing or still to be made (no file extension), holds the default name.
        if path.is_dir() or (not path.exists() and not path.suffix):
            path = path / CACHE_FILENAME
        self.path = path
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise MlctError(f"cannot create the cache directory {path.parent}: {e.strerror}; "
                            "set MLCT_CACHE to a writable directory")
        with self._db() as con:
            con.execute("BEGIN IMMEDIATE")  # serialize first-time creation across processes
            con.execute(_SCHEMA)
            version = con.execute("PRAGMA user_version").fetchone()[0]
            if version == 0:
                con.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            con.execute("COMMIT")
        if version not in (0, SCHEMA_VERSION):
            raise MlctError(f"embedding cache {path} has schema version {version}, this mlct "
                            f"reads {SCHEMA_VERSION}; delete the file or set MLCT_CACHE elsewhere")

    @contextlib.contextmanager
    def _db(self) -> Iterator[sqlite3.Connection]:
        """A fresh connection per operation; any SQLite failure becomes one clear line."""
        # Connections must not cross fork() (data-loader workers) or threads; opening one costs
        # about a tenth of a millisecond. isolation_level=None: we issue BEGIN/COMMIT ourselves.
        try:
            con = sqlite3.connect(self.path, timeout=_TIMEOUT_S, isolation_level=None)
        except sqlite3.Error as e:
            raise MlctError(f"cannot open the embedding cache {self.path}: {e}; "
                            "set MLCT_CACHE to a writable directory") from None
        try:
            yield con
        except sqlite3.DatabaseError as e:
            raise MlctError(f"embedding cache {self.path} failed: {e}; "
                            "delete the file to rebuild it") from None
        finally:
            con.close()

    def get_many(
        self, encoder_name: str, texts: Iterable[str], dim: int | None = None
    ) -> dict[str, np.ndarray]:
        """The cached (dim,) float32 embeddings of those `texts` that are cached.

        With `dim`, an entry of another size is an error (a changed encoder under an old name).
        """
        unique = list(dict.fromkeys(texts))
        found: dict[str, np.ndarray] = {}
        with self._db() as con:
            for i in range(0, len(unique), _CHUNK):
                chunk = unique[i : i + _CHUNK]
                marks = ",".join("?" * len(chunk))
                query = "SELECT text, dim, vec FROM embeddings WHERE encoder = ? AND text IN"
                rows = con.execute(f"{query} ({marks})", [encoder_name, *chunk])
                for text, n, blob in rows:
                    if (dim is not None and n != dim) or len(blob) != n * _DTYPE.itemsize:
                        raise MlctError(
                            f"embedding cache {self.path} holds a {n}-d entry for encoder "
                            f"{encoder_name!r} where {dim}-d is expected; delete the file"
                        )
                    found[text] = np.frombuffer(blob, dtype=_DTYPE).astype(np.float32)
        return found

    def put_many(self, encoder_name: str, embeddings: Mapping[str, np.ndarray | Tensor]) -> None:
        """Store (dim,) embeddings; a text already cached for this encoder keeps its entry."""
        rows = []
        for text, vec in embeddings.items():
            arr = np.asarray(vec.detach().cpu() if isinstance(vec, Tensor) else vec, dtype=_DTYPE)
            if arr.ndim != 1:
                raise MlctError(f"an embedding must be 1-d; got shape {arr.shape} for {text!r}")
            # A NaN written once would poison every later run: refuse it.
            if not np.isfinite(arr).all():
                raise MlctError(f"refusing to cache a non-finite embedding of {text!r}")
            rows.append((encoder_name, text, arr.shape[0], arr.tobytes()))
        if not rows:
            return
        with self._db() as con:
            con.execute("BEGIN IMMEDIATE")
            con.executemany(
                "INSERT OR IGNORE INTO embeddings (encoder, text, dim, vec) VALUES (?, ?, ?, ?)",
                rows,
            )
            con.execute("COMMIT")

    def count(self, encoder_name: str | None = None) -> int:
        """How many embeddings are cached (for one encoder, or for all)."""
        with self._db() as con:
            if encoder_name is None:
                return con.execute("SELECT COUNT(*) FROM embeddings").fetchone()[0]
            query = "SELECT COUNT(*) FROM embeddings WHERE encoder = ?"
            return con.execute(query, (encoder_name,)).fetchone()[0]

    def __repr__(self) -> str:
        return f"EmbeddingCache({str(self.path)!r})"


class CachedTextEncoder(TextEncoder):
    """A text encoder whose embeddings go through an `EmbeddingCache`; same name and dim."""

    def __init__(
        self, encoder: TextEncoder, cache: EmbeddingCache | str | os.PathLike | None = None
    ) -> None:
        self.inner = encoder
        self.cache = cache if isinstance(cache, EmbeddingCache) else EmbeddingCache(cache)
        self.name = encoder.name
        self.dim = encoder.dim
        self.key = encoder.cache_key

    def _encode(self, texts: list[str]) -> Tensor:
        unique = list(dict.fromkeys(texts))  # keeps first-seen order, drops repeats
        found = self.cache.get_many(self.key, unique, dim=self.dim)
        missing = [t for t in unique if t not in found]
        if missing:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(missing), desc=f"encoding captions ({self.key})", unit="text",
                       disable=len(missing) <= ENCODE_CHUNK, dynamic_ncols=True)
            for i in range(0, len(missing), ENCODE_CHUNK):
                chunk = missing[i : i + ENCODE_CHUNK]
                fresh = dict(zip(chunk, self.inner.encode(chunk).numpy()))
                self.cache.put_many(self.key, fresh)
                found.update(fresh)
                bar.update(len(chunk))
            bar.close()
        return torch.from_numpy(np.stack([found[t] for t in texts]))  # (B, dim), input order

    def __repr__(self) -> str:
        return f"CachedTextEncoder({self.inner!r}, {self.cache!r})"
