"""Save generated motions: the file format follows the extension.

- .gif / .mp4 / .png: the rendered stick figure (animation or filmstrip), motion/render.py;
- .npy: joints (T, J, 3) in the HumanML3D convention (y up, metres for HumanML3D), or the
  features (T, D) with features=True;
- .json: joints, skeleton hierarchy and fps, for the web page and any other viewer;
- .bvh: a skeleton hierarchy with per-frame local rotations and root translation, motion/bvh.py;
- .glb: a skinned humanoid with the motion as a glTF animation clip; .vrma: a VRM Animation;
  .npz: SMPL/AMASS parameters (motion/gltf.py, motion/smpl.py). Every rig format goes through
  the one rotation fit of motion/rigfit.py; `rig` (a preset of motion/rigs.py or a .json file)
  renames and re-poses the skeleton of .bvh, .glb and .fbx (.vrma is VRM's, .npz SMPL's by
  definition);
- .fbx: binary FBX 7.4, a skeleton and one animation take (Blender, Unity, Unreal, Maya),
  motion/fbx.py;
- .g1.csv / .g1.npz: the motion retargeted to the Unitree G1 robot's joint angles, MuJoCo's qpos
  per frame (motion/robots/).

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
    """What a writer reads from a motion (mlct.generate.output.generated.GeneratedMotion has it): a
    protocol, so that this module does not import the one that imports it."""

    text: str
    joints: np.ndarray  # (T, J, 3)
    features: np.ndarray  # (T, D)
    fps: float
    skeleton: str
    seed: int | None


FORMATS = (".gif", ".mp4", ".png", ".npy", ".json", ".bvh", ".glb", ".fbx", ".vrma", ".npz")
RIG_FORMATS = (".bvh", ".glb", ".fbx")  # the formats a --rig retargets
FIXED_RIGS = {".vrma": "vrm", ".npz": "smpl"}  # the formats whose rig is their own
ROBOT_FORMATS = (".g1.csv", ".g1.npz")  # named by a double extension: .npz alone is SMPL's
JSON_FORMAT = "mlct-motion"
JSON_DECIMALS = 4  # 0.1 mm: far below what a viewer shows, and a third of the digits


def check_format(path: str | os.PathLike) -> str:
    """The lower-case extension of path when it is a format we write; MlctError otherwise."""
    name = Path(path).name.lower()
    robot = next((f for f in ROBOT_FORMATS if name.endswith(f)), None)
    if robot is not None:
        return robot
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise MlctError(f"cannot tell the format of '{Path(path).name}': the name must end in "
                        f"{', '.join(FORMATS + ROBOT_FORMATS)}")
    return suffix


def check_rig(rig: str | os.PathLike | None, suffix: str) -> None:
    """A one-line MlctError unless `rig` fits a file ending in suffix (checked before generating):
    a preset or a readable .json rig, for a format that takes one."""
    if rig is None:
        return
    from mlct.motion.rigs import get_rig
    from mlct.motion.skeleton import HUMANML3D

    if suffix in FIXED_RIGS and str(rig).lower() == FIXED_RIGS[suffix]:
        return
    if suffix not in RIG_FORMATS:
        own = "; ".join(f"{f} is always {r}" for f, r in FIXED_RIGS.items())
        raise MlctError(f"--rig applies to {', '.join(RIG_FORMATS)} files, not {suffix} ({own})")
    get_rig(rig, HUMANML3D)


def motion_json(motion: GeneratedMotion) -> dict[str, Any]:
    """A JSON-ready dict: text, fps, skeleton (joint names, parents), joints (T, J, 3) rounded,
    foot_contacts (T, 2): [left, right] 1 where that foot stands on the floor
    (motion/foot_lock.py: foot_contacts)."""
    from mlct.motion.foot_lock import foot_contacts

    skeleton = get_skeleton(motion.skeleton)
    return {"format": JSON_FORMAT, "version": 1, "text": motion.text, "fps": motion.fps,
            "skeleton": skeleton.name, "unit": skeleton.unit,
            "joint_names": list(skeleton.joint_names), "parents": list(skeleton.parents),
            "frames": len(motion.joints), "seed": motion.seed,
            "joints": np.round(motion.joints.astype(np.float64), JSON_DECIMALS).tolist(),
            "foot_contacts": foot_contacts(motion.joints, skeleton,
                                           fps=motion.fps).astype(int).tolist()}


def save_motion(motion: GeneratedMotion, path: str | os.PathLike, features: bool = False,
                rig: str | os.PathLike | None = None) -> Path:
    """Write motion to path in the format its extension names; returns the path. `rig`: a
    retarget preset or .json file for .bvh, .glb and .fbx (module doc)."""
    if not isinstance(path, (str, os.PathLike)):
        raise MlctError(f"path must be a file name (str or Path), not {type(path).__name__}")
    path = Path(path)
    suffix = check_format(path)
    if features and suffix != ".npy":
        raise MlctError(f"features can only be saved as .npy, not {suffix}")
    check_rig(rig, suffix)
    if path.is_dir():  # else the error would name the temporary file that cannot replace it
        raise MlctError(f"cannot save to {path}: it is a directory")
    skeleton = get_skeleton(motion.skeleton)
    if suffix == ".npy":
        save_npy(path, motion.features if features else motion.joints)
    elif suffix == ".json":
        write_text(path, json.dumps(motion_json(motion), separators=(",", ":")) + "\n")
    elif suffix == ".bvh":
        from mlct.motion.bvh import write_bvh

        write_bvh(path, motion.joints, skeleton, motion.fps, rig=rig)
    elif suffix == ".glb":
        from mlct.motion.gltf import write_glb

        write_glb(path, motion.joints, skeleton, motion.fps, rig=rig)
    elif suffix == ".fbx":
        from mlct.motion.fbx import write_fbx

        write_fbx(path, motion.joints, skeleton, motion.fps, rig=rig)
    elif suffix == ".vrma":
        from mlct.motion.gltf import write_vrma

        write_vrma(path, motion.joints, skeleton, motion.fps)
    elif suffix in ROBOT_FORMATS:
        from mlct.motion.robots.files import write_robot
        from mlct.motion.robots.retarget import retarget_g1

        write_robot(path, retarget_g1(motion.joints, skeleton, motion.fps))
    elif suffix == ".npz":
        from mlct.motion.smpl import write_smpl_npz

        write_smpl_npz(path, motion.joints, skeleton, motion.fps)
    else:
        from mlct.motion.render import render_motion

        render_motion(motion.joints, path, skeleton=skeleton, title=motion.text, fps=motion.fps)
    return path


def export_bytes(motion: GeneratedMotion, suffix: str, features: bool = False,
                 rig: str | None = None) -> bytes:
    """The bytes save_motion would write for a file ending in suffix (for HTTP downloads)."""
    suffix = check_format(f"motion{suffix}")
    if suffix == ".npy":
        buffer = io.BytesIO()
        np.save(buffer, motion.features if features else motion.joints)
        return buffer.getvalue()
    with tempfile.TemporaryDirectory(prefix="mlct-export-") as tmp:
        return save_motion(motion, Path(tmp) / f"motion{suffix}", features, rig).read_bytes()
