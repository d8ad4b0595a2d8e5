"""A dataset made small enough to carry to a lent GPU machine, and made whole again there.

    python bench/gpu/dataset_carry.py pack DATASET OUT.tar.xz   # here
    python bench/gpu/dataset_carry.py unpack IN.tar.xz PARENT   # there: PARENT/<name>

`pack` keeps everything but the motions' files, and the features (new_joint_vecs) in one npz of
float16: a real corpus of 222 motions is 11 MB instead of 33 (float16 rounds its features by
under a millimetre). `unpack` writes the features back as float32 .npy and recovers the joint
positions from them, as the importer does.
"""

from __future__ import annotations

import io
import shutil
import sys
import tarfile
from pathlib import Path

import numpy as np

from mlct.data.layout import FEATURES_DIR, JOINTS_DIR
from mlct.motion.joints import features_to_joints

PACKED = "features_fp16.npz"


def pack(dataset: Path, out: Path) -> None:
    features = {f.stem: np.load(f).astype(np.float16)
                for f in sorted((dataset / FEATURES_DIR).glob("*.npy"))}
    buffer = io.BytesIO()
    np.savez(buffer, **features)
    with tarfile.open(out, "w:xz") as tar:
        for path in sorted(dataset.iterdir()):
            if path.name not in (FEATURES_DIR, JOINTS_DIR):
                tar.add(path, arcname=f"{dataset.name}/{path.name}")
        info = tarfile.TarInfo(f"{dataset.name}/{PACKED}")
        info.size = buffer.getbuffer().nbytes
        buffer.seek(0)
        tar.addfile(info, buffer)
    print(f"{dataset}: {len(features)} motions -> {out} ({out.stat().st_size / 2**20:.1f} MiB)")


def unpack(archive: Path, parent: Path) -> None:
    with tarfile.open(archive) as tar:
        name = tar.getnames()[0].split("/")[0]
        shutil.rmtree(parent / name, ignore_errors=True)  # an earlier unpacking's
        tar.extractall(parent, filter="data")
    dataset = parent / name
    (dataset / FEATURES_DIR).mkdir()
    (dataset / JOINTS_DIR).mkdir()
    with np.load(dataset / PACKED) as packed:
        for stem in packed.files:
            features = packed[stem].astype(np.float32)
            np.save(dataset / FEATURES_DIR / f"{stem}.npy", features)
            np.save(dataset / JOINTS_DIR / f"{stem}.npy", features_to_joints(features))
        count = len(packed.files)
    (dataset / PACKED).unlink()
    print(f"{archive} -> {dataset}: {count} motions")


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] not in ("pack", "unpack"):
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        sys.exit(2)
    (pack if sys.argv[1] == "pack" else unpack)(Path(sys.argv[2]), Path(sys.argv[3]))
