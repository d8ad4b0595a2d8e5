"""The static site's large binaries stored gzipped, unpacked by the page (static/model.js:
`fetchBytes`, the browser's DecompressionStream) and by the Python reference (`unpacked`).

Why: the site's goal is <= 40 MB on disk. Its two largest files compress well as
files and not at all as anything smaller: onnxruntime-web's WASM binary (14.2 MB -> 3.7 MB) and
the int8 text encoder (23.0 -> 17.9 MB); the float16 graphs gain 8-9 %, which the arm-pair
decoder and the critic's graph made worth it (MIN_GAIN). Stored so, the bundled model's site
takes 32.6 MB with every number unchanged (quantizing further costs quality: docs/web.md). A server that compresses
(GitHub Pages, nginx) would have sent them gzipped anyway; `python -m http.server`, a file share
or a zip of the site now carry the small files too.

The page reads the first two bytes: gzip's magic (1f 8b) is unpacked, anything else (a server
that unpacked a `.gz` itself by sending Content-Encoding: gzip, or a site exported with
--no-gzip) is used as it is. An ONNX graph starts with a protobuf field (08) and a WASM binary
with "\\0asm", so neither is mistaken for gzip.
"""

from __future__ import annotations

import gzip
import os
import shutil
import tempfile
import weakref
from pathlib import Path

SUFFIX = ".gz"
LEVEL = 9
# Unpacking costs the page time when it opens (2-core machine at load average 7.5: 1.1 s more
# for the text encoder, 0.2 s for the WASM binary, 0.45 s for the float16 graphs together;
# bench/web_speed.py --unpack); a file is stored gzipped only when that saves at least this
# share of it.
# 5 %: the float16 graphs (denoiser, decoder, critic) save 1.4 MB together, which keeps the site
# of the arm-pair model with its critic under the 40 MB goal (40.5 MB with them plain).
MIN_GAIN = 0.05


def gzip_file(path: Path, min_gain: float = MIN_GAIN) -> Path:
    """Replace path by path.gz (level 9, no time stamp: the same input gives the same bytes)
    when that is at least min_gain smaller; returns the path kept."""
    target = path.with_name(path.name + SUFFIX)
    with open(path, "rb") as src, open(target, "wb") as raw:
        with gzip.GzipFile(filename="", mode="wb", fileobj=raw, compresslevel=LEVEL,
                           mtime=0) as out:
            shutil.copyfileobj(src, out, 1 << 20)
    if target.stat().st_size > (1 - min_gain) * path.stat().st_size:
        target.unlink()
        return path
    path.unlink()
    return target


def unpacked(paths: dict[str, Path]) -> tuple[dict[str, Path], Path | None]:
    """The same files with each `.gz` one unpacked into a new temporary folder, and that
    folder (None when nothing was packed); `remove_with` ties its removal to an object."""
    if not any(p.name.endswith(SUFFIX) for p in paths.values()):
        return dict(paths), None
    folder = Path(tempfile.mkdtemp(prefix="mlct-site-"))
    out = {}
    for key, path in paths.items():
        if not path.name.endswith(SUFFIX):
            out[key] = path
            continue
        out[key] = folder / path.name[:-len(SUFFIX)]
        with gzip.open(path, "rb") as src, open(out[key], "wb") as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
    return out, folder


def remove_with(owner: object, folder: Path | None) -> None:
    """Remove folder when owner is garbage collected (or at exit)."""
    if folder is not None:
        weakref.finalize(owner, shutil.rmtree, str(folder), True)


def is_gzip(path: str | os.PathLike) -> bool:
    with open(path, "rb") as handle:
        return handle.read(2) == b"\x1f\x8b"
