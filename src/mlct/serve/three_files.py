"""three.js for `mlct serve`'s page: the pinned npm package, unpacked once into a cache folder.

The page's skinned humanoid (static/body.js) needs three, its GLTFLoader and OrbitControls.
They are not copied into mlct (third-party code stays in its own package, as plotly.js stays in
its wheel): the server takes them from the three tarball that the static site pins
(site/npm/package-lock.json, checked against its sha512 by site/vendor.py), unpacks the few
files the page imports into ~/.cache/mlct/web/three-VERSION/ (or MLCT_WEB_CACHE) and serves
that folder at /static/three/. The tarball is fetched from the npm registry the first time, as
`mlct export-web` does. Without it (no network, no cache) the page still works: the skeleton
view is plain canvas code and only the humanoid is missing, with the reason in its caption.
"""

from __future__ import annotations

import os
import shutil
import tarfile
import tempfile
from pathlib import Path

from mlct.errors import MlctError
from mlct.serve.site.vendor import cache_dir, pins, tarball

# The tarball's files -> their paths under /static/three/; the relative layout of
# examples/jsm is kept, so GLTFLoader's own "../utils/*.js" imports resolve.
FILES = {
    "package/build/three.module.js": "three.module.js",
    "package/build/three.core.js": "three.core.js",  # three.module.js imports it
    "package/examples/jsm/loaders/GLTFLoader.js": "loaders/GLTFLoader.js",
    "package/examples/jsm/utils/BufferGeometryUtils.js": "utils/BufferGeometryUtils.js",
    "package/examples/jsm/utils/SkeletonUtils.js": "utils/SkeletonUtils.js",  # GLTFLoader's too
    "package/examples/jsm/controls/OrbitControls.js": "controls/OrbitControls.js",
    "package/LICENSE": "LICENSE",
}


def three_dir(vendor: str | os.PathLike | None = None, fetch: bool = True) -> Path:
    """The folder of three's page files, unpacked from the pinned tarball when not yet there.

    fetch=False never goes to the network (a server being built, a test): then a tarball
    missing from the cache is an MlctError, as one that can be neither found nor fetched is
    (vendor.tarball's message). The folder is made in a temporary sibling and renamed into place, so a crash
    half-way leaves no half-unpacked folder for the next server to serve."""
    pin = next(p for p in pins() if p.name == "three")
    folder = cache_dir() / f"three-{pin.version}"
    if all((folder / name).is_file() for name in FILES.values()):
        return folder
    if vendor is None and not fetch and not (cache_dir() / pin.tarball).is_file():
        raise MlctError(f"{pin.tarball} is not in {cache_dir()} (`mlct serve` or `mlct "
                        f"export-web` fetches it from the npm registry)")
    archive_path = tarball(pin, None if vendor is None else Path(vendor))
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".three-{pin.version}-", dir=folder.parent))
    try:
        with tarfile.open(archive_path) as archive:
            for member, name in FILES.items():
                try:
                    source = archive.extractfile(member)
                except KeyError:
                    source = None
                if source is None:
                    raise MlctError(f"{pin.tarball} has no {member}")
                (staging / name).parent.mkdir(parents=True, exist_ok=True)
                with source, open(staging / name, "wb") as out:
                    shutil.copyfileobj(source, out)
        if folder.exists():  # an incomplete folder (an older layout, a deleted file)
            shutil.rmtree(folder, ignore_errors=True)
        try:
            os.replace(staging, folder)
        except OSError:  # another server unpacked it first: theirs is as good
            if not all((folder / name).is_file() for name in FILES.values()):
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return folder
