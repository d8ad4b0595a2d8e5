"""Save generated motions: the file format follows the extension.

- .gif / .mp4 / .png: the rendered stick figure (animation or filmstrip), motion/render.py;
- .npy: joints (T, J, 3) in the HumanML3D convention (y up, metres for HumanML3D), or the
  features (T, D) with features=True;
- .json: joints, skeleton hierarchy and fps, for the web page and any other viewer;
- .bvh: a skeleton hierarchy with per-frame local rotations and root translation, motion/bvh.py.

One function, `save_motion`, serves the CLI, `GeneratedMotion.save` and the server (through
`export_bytes`).
"""

from __future__ import annotations

import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from mlct.errors import MlctError
from mlct.io import save_npy, write_text
from mlct.motion.skeleton import get_skeleton


class GeneratedMotion(Protocol):
    """What a writer reads from a motion (mlct.generate.generated.GeneratedMotion has it): a
    protocol, so that this module does not import the one that imports it."""

    text: str
    joints: np.ndarray  # (T, J, 3)
    features: np.ndarray  # (T, D)
    fps: float
    skeleton: str
    seed: int | None


FORMATS = (".gif", ".mp4", ".png", ".npy", ".json", ".bvh")
JSON_FORMAT = "mlct-motion"
JSON_DECIMALS = 4  # 0.1 mm: far below what a viewer shows, and a third of the digits


def check_format(path: str | os.PathLike) -> str:
    """The lower-case extension of path when it is a format we write; MlctError otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise MlctError(f"cannot tell the format of '{Path(path).name}': the name must end in "
                        f"{', '.join(FORMATS)}")
    return suffix


def motion_json(motion: GeneratedMotion) -> dict[str, Any]:
    """A JSON-ready dict: text, fps, skeleton (joint names, parents), joints (T, J, 3) rounded."""
    skeleton = get_skeleton(motion.skeleton)
    return {"format": JSON_FORMAT, "version": 1, "text": motion.text, "fps": motion.fps,
            "skeleton": skeleton.name, "unit": skeleton.unit,
            "joint_names": list(skeleton.joint_names), "parents": list(skeleton.parents),
            "frames": len(motion.joints), "seed": motion.seed,
            "joints": np.round(motion.joints.astype(np.float64), JSON_DECIMALS).tolist()}


def save_motion(motion: GeneratedMotion, path: str | os.PathLike, features: bool = False) -> Path:
    """Write motion to path in the format its extension names; returns the path."""
    if not isinstance(path, (str, os.PathLike)):
        raise MlctError(f"path must be a file name (str or Path), not {type(path).__name__}")
    path = Path(path)
    suffix = check_format(path)
    if features and suffix != ".npy":
        raise MlctError(f"features can only be saved as .npy, not {suffix}")
    if path.is_dir():  # else the error would name the temporary file that cannot replace it
        raise MlctError(f"cannot save to {path}: it is a directory")
    skeleton = get_skeleton(motion.skeleton)
    if suffix == ".npy":
        save_npy(path, motion.features if features else motion.joints)
    elif suffix == ".json":
        write_text(path, json.dumps(motion_json(motion), separators=(",", ":")) + "\n")
    elif suffix == ".bvh":
        from mlct.motion.bvh import write_bvh

        write_bvh(path, motion.joints, skeleton, motion.fps)
    else:
        from mlct.motion.render import render_motion

        render_motion(motion.joints, path, skeleton=skeleton, title=motion.text, fps=motion.fps)
    return path


def export_bytes(motion: GeneratedMotion, suffix: str, features: bool = False) -> bytes:
    """The bytes save_motion would write for a file ending in suffix (for HTTP downloads)."""
    suffix = check_format(f"motion{suffix}")
    if suffix == ".npy":
        buffer = io.BytesIO()
        np.save(buffer, motion.features if features else motion.joints)
        return buffer.getvalue()
    with tempfile.TemporaryDirectory(prefix="mlct-export-") as tmp:
        return save_motion(motion, Path(tmp) / f"motion{suffix}", features).read_bytes()
