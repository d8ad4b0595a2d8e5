"""The npm files of the static site: onnxruntime-web (the WASM runtime of the graphs), three
(the 3D view) and gifenc (the GIF download), at the versions that npm/package-lock.json pins,
copied into SITE/vendor/.

Where they come from. Not from the repository (onnxruntime-web's WASM binary alone is 14 MB a
version, its package 33 MB) and not from a CDN at run time (the site must work offline). At
export time, the package tarballs are taken from a cache folder, `MLCT_WEB_CACHE` or
~/.cache/mlct/web; a missing one is fetched once from the npm registry, with npm when it is
installed (`npm pack`), else over HTTPS from the registry's tarball URL, and checked against
the sha512 that the lock file pins before anything is read from it. A machine without network
access gets the tarballs elsewhere (`npm pack onnxruntime-web@1.30.0 three@0.187.0
gifenc@1.0.3`) and passes
their folder as `mlct export-web --vendor DIR`.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
import subprocess
import tarfile
import tempfile
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from mlct.errors import MlctError, first_line

LOCK = Path(__file__).resolve().parent / "npm" / "package-lock.json"
REGISTRY = "https://registry.npmjs.org"

# Per package: the files of its tarball the site needs -> their names under SITE/vendor/.
FILES: dict[str, dict[str, str]] = {
    "onnxruntime-web": {
        # the WASM-only build (no WebGL / WebGPU code), its loader and the SIMD+threads binary
        "package/dist/ort.wasm.min.mjs": "ort.wasm.min.mjs",
        "package/dist/ort-wasm-simd-threaded.mjs": "ort-wasm-simd-threaded.mjs",
        "package/dist/ort-wasm-simd-threaded.wasm": "ort-wasm-simd-threaded.wasm",
        "package/README.md": "onnxruntime-web.README.md",
    },
    "three": {
        "package/build/three.module.js": "three.module.js",
        "package/build/three.core.js": "three.core.js",
        "package/examples/jsm/controls/OrbitControls.js": "OrbitControls.js",
        "package/examples/jsm/exporters/GLTFExporter.js": "GLTFExporter.js",  # the GLB download
        "package/LICENSE": "three.LICENSE",
    },
    "gifenc": {  # the GIF download: one palette for the clip, LZW in the page
        "package/dist/gifenc.esm.js": "gifenc.esm.js",
        "package/LICENSE.md": "gifenc.LICENSE.md",
    },
}


@dataclass(frozen=True)
class Pin:
    name: str
    version: str
    integrity: str  # "sha512-<base64>", as npm's lock file writes it

    @property
    def tarball(self) -> str:
        return f"{self.name}-{self.version}.tgz"


def pins() -> list[Pin]:
    """The pinned packages of the lock file, in FILES' order."""
    packages = json.loads(LOCK.read_text(encoding="utf-8"))["packages"]
    out = []
    for name in FILES:
        entry = packages[f"node_modules/{name}"]
        out.append(Pin(name, entry["version"], entry["integrity"]))
    return out


def cache_dir() -> Path:
    return Path(os.environ.get("MLCT_WEB_CACHE") or Path.home() / ".cache" / "mlct" / "web")


def _digest_ok(path: Path, pin: Pin) -> bool:
    algorithm, _, expected = pin.integrity.partition("-")
    digest = hashlib.new(algorithm)
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return base64.b64encode(digest.digest()).decode() == expected


def _fetch(pin: Pin, into: Path) -> Path:
    """Download pin's tarball into the folder `into` (npm pack, else HTTPS); its path."""
    into.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=into) as tmp:
        npm = shutil.which("npm")
        try:
            if npm:
                subprocess.run([npm, "pack", f"{pin.name}@{pin.version}", "--silent",
                                "--pack-destination", tmp], check=True, capture_output=True,
                               timeout=600)
            else:
                url = f"{REGISTRY}/{pin.name}/-/{pin.tarball}"
                with urllib.request.urlopen(url, timeout=120) as response, \
                        open(Path(tmp) / pin.tarball, "wb") as f:
                    shutil.copyfileobj(response, f)
        except (OSError, subprocess.SubprocessError) as error:
            why = (error.stderr.decode(errors="replace").strip().splitlines() or [""])[-1] \
                if isinstance(error, subprocess.CalledProcessError) else first_line(error)
            raise MlctError(f"cannot fetch {pin.name} {pin.version} from the npm registry "
                            f"({why or error}); on a machine with network access run `npm pack "
                            f"{pin.name}@{pin.version}` and pass the tarball's folder as "
                            f"--vendor DIR") from None
        got = Path(tmp) / pin.tarball
        if not got.is_file():
            raise MlctError(f"npm pack did not write {pin.tarball}")
        if not _digest_ok(got, pin):
            raise MlctError(f"{pin.tarball} from the registry does not have the sha512 that "
                            f"{LOCK.name} pins; not used")
        os.replace(got, into / pin.tarball)
    return into / pin.tarball


def tarball(pin: Pin, vendor: Path | None = None) -> Path:
    """pin's checked tarball: from --vendor DIR when given, else the cache (fetched if new)."""
    if vendor is not None:
        path = Path(vendor) / pin.tarball
        if not path.is_file():
            raise MlctError(f"{vendor}: no {pin.tarball} (make it with `npm pack "
                            f"{pin.name}@{pin.version}`)")
    else:
        path = cache_dir() / pin.tarball
        if not path.is_file():
            path = _fetch(pin, cache_dir())
    if not _digest_ok(path, pin):
        raise MlctError(f"{path} is not the {pin.name} {pin.version} that {LOCK.name} pins "
                        f"(its sha512 differs); delete it and export again")
    return path


def copy_vendor_files(into: str | os.PathLike, vendor: str | os.PathLike | None = None
                      ) -> dict[str, str]:
    """Copy the site's npm files into the folder `into`; returns {package: version}."""
    into = Path(into)
    into.mkdir(parents=True, exist_ok=True)
    versions = {}
    for pin in pins():
        with tarfile.open(tarball(pin, None if vendor is None else Path(vendor))) as archive:
            for member, name in FILES[pin.name].items():
                source = archive.extractfile(member)
                if source is None:
                    raise MlctError(f"{pin.tarball} has no {member}")
                with source, open(into / name, "wb") as out:
                    shutil.copyfileobj(source, out)
        versions[pin.name] = pin.version
    return versions
