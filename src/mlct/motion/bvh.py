"""BVH export and import: joint positions <-> a skeleton hierarchy with per-frame rotations.

Writing. A BVH skeleton is rigid and rotates each joint as a whole, while mlct motions are joint
positions. The file is fitted to the positions so that forward kinematics gives them back:

- the hierarchy is the skeleton's (joint names, parents), depth first; every joint without
  children ends in an `End Site` (half its own bone, along it: only drawn, never moves a joint);
- the skeleton and its rotations are the shared rotation fit's (motion/rigfit.py): bone lengths
  fixed at the motion's median, OFFSETs along the skeleton's natural rest pose
  (`Skeleton.rest_directions`: standing, facing +Z, y up), the root trajectory exact, limbs by
  two-bone IK (planted feet stay planted), twist smooth over time;
- the root has 6 channels (Xposition Yposition Zposition Zrotation Xrotation Yrotation), the
  others 3; angles in degrees, intrinsic Z-X-Y as the channel order says (what Blender,
  MotionBuilder and most BVH readers apply), unwrapped over time so no angle jumps by 360.

Units: centimetres, the de facto BVH unit (mocap exports, MotionBuilder, game-engine importers).
HumanML3D metres are multiplied by 100, KIT-ML millimetres divided by 10. In Blender's BVH
importer set Scale to 0.01 to get metres. A rig preset (`rig=`, rigs.py) gives the file that
rig's joint names, rest pose, up axis and unit instead.

Exactness: the file gives back the fitted skeleton's joints (to the 1e-4 cm of the text). Those
are the motion's own wherever its bones keep their length and each multi-child group keeps its
shape, as in captured or procedural motion; a generated motion whose bones stretch comes back
with each joint off by about its own bone's stretch, which no rigid skeleton can show.

Reading (`read_bvh`) parses with bvhio (a maintained BVH package) and returns world positions
of every joint, in the file's units; `mlct data import --bvh` maps them onto a skeleton.
"""

from __future__ import annotations

import io
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.io import write_text
from mlct.motion.rotations import quat_to_matrix
from mlct.motion.rigfit import check_joints, children_of, fit_rig
from mlct.motion.rigs import Rig, get_rig
from mlct.motion.skeleton import Skeleton

BVH_UNIT = "cm"
TO_CENTIMETRES = {"m": 100.0, "mm": 0.1}
EULER_ORDER = "ZXY"  # intrinsic, as listed in CHANNELS
ROOT_CHANNELS = "Xposition Yposition Zposition Zrotation Xrotation Yrotation"
JOINT_CHANNELS = "Zrotation Xrotation Yrotation"
END_SITE_FRACTION = 0.5
DECIMALS = 4  # 1e-4 cm and 1e-4 degrees: far below anything visible


@dataclass(frozen=True)
class BvhPose:
    """A motion fitted to a rigid BVH skeleton, in centimetres."""

    order: tuple[int, ...]  # skeleton joints in file order (depth first)
    offsets: np.ndarray  # (J, 3) rest offsets from each joint's parent (root: 0)
    end_sites: dict[int, np.ndarray]  # leaf joint -> (3,) End Site offset
    root_positions: np.ndarray  # (T, 3)
    euler: np.ndarray  # (T, J, 3) local rotations, degrees, in EULER_ORDER


def bvh_frame(skeleton: Skeleton, rig: Rig | None) -> tuple[np.ndarray, float]:
    """(3, 3) rotation from mlct's frame to the file's and the skeleton-unit -> file-unit scale:
    the rig's axes and unit, or y up in centimetres without a rig."""
    if rig is None:
        return np.eye(3), TO_CENTIMETRES[skeleton.unit]
    return rig.axes, rig.per_metre * TO_CENTIMETRES[skeleton.unit] / 100.0


def euler_zxy_degrees(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 3) angles in degrees, intrinsic Z, X, Y (EULER_ORDER,
    the order of CHANNELS): m = Rz(a) Rx(b) Ry(c) with b in [-90, 90], as scipy's
    Rotation.as_euler("ZXY") gives them, without scipy's import (~0.4 s of a one-off .bvh).

    From the product written out: m[2, 1] = sin b, (m[2, 0], m[2, 2]) = cos b (-sin c, cos c)
    and (m[0, 1], m[1, 1]) = cos b (-sin a, cos a). At b = +-90 degrees (gimbal lock: a joint
    turned straight up or down about X) only a + c or a - c is defined, by (m[1, 0], m[0, 0]);
    c is 0 there, as in scipy."""
    cos_b = np.hypot(m[..., 2, 0], m[..., 2, 2])
    b = np.arctan2(m[..., 2, 1], cos_b)
    locked = cos_b < 1e-7
    a = np.where(locked, np.arctan2(m[..., 1, 0], m[..., 0, 0]),
                 np.arctan2(-m[..., 0, 1], m[..., 1, 1]))
    c = np.where(locked, 0.0, np.arctan2(-m[..., 2, 0], m[..., 2, 2]))
    return np.degrees(np.stack([a, b, c], axis=-1))


def fit_bvh(joints: np.ndarray, skeleton: Skeleton, rig: Rig | None = None,
            fps: float | None = None) -> BvhPose:
    """Fit (T, J, 3) joint positions (skeleton units) to a rigid BVH skeleton (module doc), in
    the rig's rest pose, axes and unit when one is given (rigs.py)."""
    fit = fit_rig(check_joints(joints, skeleton, "BVH export"), skeleton,
                  None if rig is None else rig.rest_directions, fps=fps)
    axes, scale = bvh_frame(skeleton, rig)
    local = axes @ fit.local @ axes.T  # the same turns, seen in the file's frame
    euler = np.unwrap(euler_zxy_degrees(local), period=360.0, axis=0)
    children = children_of(skeleton.parents)
    offsets = fit.offsets @ axes.T * scale
    end_sites = {j: offsets[j] * END_SITE_FRACTION for j in range(skeleton.n_joints)
                 if not children[j]}
    return BvhPose(order=fit.order, offsets=offsets, end_sites=end_sites,
                   root_positions=fit.root @ axes.T * scale, euler=euler)


def _vector(values: np.ndarray, places: int = DECIMALS) -> str:
    return " ".join(f"{v:.{places}f}" for v in values)


def bvh_text(joints: np.ndarray, skeleton: Skeleton, fps: float,
             rig: str | os.PathLike | Rig | None = None) -> str:
    """The BVH file of (T, J, 3) joint positions at `fps` frames per second (module doc)."""
    try:
        rate = float(fps)
    except (TypeError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise MlctError(f"BVH export needs a positive frame rate, got {fps!r}")
    target = get_rig(rig, skeleton)
    names = skeleton.joint_names if target is None else target.joint_names
    pose = fit_bvh(joints, skeleton, target, fps=rate)
    places = DECIMALS if target is None or target.unit == "cm" else DECIMALS + 2  # 1e-4 cm
    children = children_of(skeleton.parents)
    lines = ["HIERARCHY"]

    def joint_block(joint: int, depth: int) -> None:
        pad = "  " * depth
        keyword = "ROOT" if depth == 0 else "JOINT"
        channels = f"6 {ROOT_CHANNELS}" if depth == 0 else f"3 {JOINT_CHANNELS}"
        lines.extend([f"{pad}{keyword} {names[joint]}", f"{pad}{{",
                      f"{pad}  OFFSET {_vector(pose.offsets[joint], places)}",
                      f"{pad}  CHANNELS {channels}"])
        for kid in children[joint]:
            joint_block(kid, depth + 1)
        if not children[joint]:
            lines.extend([f"{pad}  End Site", f"{pad}  {{",
                          f"{pad}    OFFSET {_vector(pose.end_sites[joint], places)}",
                          f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint_block(pose.order[0], 0)
    n_frames = len(pose.root_positions)
    # Channel values per frame in file order: root position, then Z X Y angles of each joint.
    values = np.concatenate([pose.root_positions, pose.euler[:, list(pose.order)].reshape(
        n_frames, -1)], axis=1)
    digits = np.array([places] * 3 + [DECIMALS] * (values.shape[1] - 3))
    buffer = io.StringIO()
    np.savetxt(buffer, np.round(values * 10.0**digits) / 10.0**digits + 0.0,  # no "-0.0000"
               fmt=[f"%.{d}f" for d in digits])
    lines.extend(["MOTION", f"Frames: {n_frames}", f"Frame Time: {1.0 / rate:.9g}"])
    return "\n".join(lines) + "\n" + buffer.getvalue()


def write_bvh(path: str | os.PathLike, joints: np.ndarray, skeleton: Skeleton,
              fps: float, rig: str | os.PathLike | Rig | None = None) -> None:
    """Write (T, J, 3) joint positions as a BVH file at `fps`, atomically (module doc)."""
    write_text(path, bvh_text(joints, skeleton, fps, rig))


@dataclass(frozen=True)
class BvhClip:
    """A BVH file read back: its joints (End Sites excluded) and their world positions."""

    joint_names: tuple[str, ...]
    parents: tuple[int, ...]  # -1 for the root
    positions: np.ndarray  # (T, N, 3) world positions, in the file's units
    frame_time: float  # seconds

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time


_END_OF_FILE = "%mlct-end-of-file%"  # read_bvh's last line: no BVH rule accepts it


def _check_bvh_shape(path: Path) -> str:
    """The file's text; a one-line error unless it has a BVH's two sections."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(64).lstrip()
            handle.seek(0)
            text = handle.read().decode("utf-8")
    except OSError as error:
        raise MlctError(f"{path}: cannot read ({error.strerror})") from None
    except UnicodeDecodeError as error:
        raise MlctError(f"{path}: not a readable BVH file (not UTF-8 text: byte "
                        f"0x{error.object[error.start]:02x} at offset {error.start})") from None
    if not head:
        raise MlctError(f"{path}: not a readable BVH file (it is empty)")
    if not head.upper().startswith(b"HIERARCHY") or "MOTION" not in text or "Frames:" not in text:
        raise MlctError(f"{path}: not a readable BVH file (it needs a HIERARCHY section, then "
                        f"MOTION with Frames: and Frame Time:)")
    return text


def read_bvh(path: str | os.PathLike, end_sites: bool = False) -> BvhClip:
    """Parse a BVH file (bvhio) and compute every joint's world position per frame; with
    `end_sites`, each End Site too, as a joint named after its parent plus ".end" (a rig
    whose feet end in one has no toe joint, but its End Site is where the toes are).

    Forward kinematics as the format defines it: a joint's channels give its local translation
    (the OFFSET unless position channels override it) and its rotation (Euler angles in the
    order the CHANNELS line lists them); the world rotation accumulates from the root.
    Vectorized over frames: bvhio's own hierarchy does the same one frame at a time, ~10x slower.
    """
    import bvhio  # the BVH reader of `mlct data import --bvh`; export needs no package

    path = Path(path)
    text = _check_bvh_shape(path)
    # bvhio's parser skips blank lines by reading on until one has a token, and at the end of
    # the file it reads "" forever: a file that ends early (fewer frames than `Frames:` says, a
    # cut hierarchy) would hang it. It parses a copy ending in a line that no rule accepts.
    with tempfile.TemporaryDirectory(prefix="mlct-bvh-") as tmp:
        copy = Path(tmp) / "clip.bvh"
        copy.write_text(f"{text}\n{_END_OF_FILE}\n", encoding="utf-8")
        try:
            container = bvhio.readAsBvh(str(copy))
        except (OSError, SyntaxError, ValueError, IndexError, TypeError) as error:
            if _END_OF_FILE in (getattr(error, "text", None) or ""):
                raise MlctError(f"{path}: not a readable BVH file (it ends early: fewer lines "
                                f"than its hierarchy or its Frames: count needs)") from None
            raise MlctError(f"{path}: not a readable BVH file ({first_line(error)})") from None
    n_frames = int(container.FrameCount)
    if n_frames < 1 or not container.FrameTime > 0:
        raise MlctError(f"{path}: a BVH file needs frames and a positive Frame Time "
                        f"(found {n_frames} frames, Frame Time {container.FrameTime})")
    layout = [entry[0] for entry in container.Root.layout()]  # depth first, parents first
    index = {id(joint): i for i, joint in enumerate(layout)}
    parents = [-1] * len(layout)
    for joint in layout:
        for child in joint.Children:
            parents[index[id(child)]] = index[id(joint)]
    positions = np.empty((n_frames, len(layout), 3))
    world = np.empty((n_frames, len(layout), 3, 3))
    for i, joint in enumerate(layout):
        keys = joint.Keyframes
        if len(keys) != n_frames:
            raise MlctError(f"{path}: joint {joint.Name} has {len(keys)} frames of motion, "
                            f"the header says {n_frames}")
        local_pos = np.array([tuple(k.Position) for k in keys])  # (T, 3)
        quats = np.array([(k.Rotation.w, k.Rotation.x, k.Rotation.y, k.Rotation.z) for k in keys])
        local_rot = quat_to_matrix(quats)  # (T, 3, 3)
        parent = parents[i]
        if parent < 0:
            positions[:, i], world[:, i] = local_pos, local_rot
        else:
            positions[:, i] = positions[:, parent] + np.einsum("tij,tj->ti", world[:, parent],
                                                               local_pos)
            world[:, i] = world[:, parent] @ local_rot
    names = [j.Name for j in layout]
    if end_sites:
        tips = [(i, np.array(tuple(j.EndSite))) for i, j in enumerate(layout)
                if not j.Children and j.EndSite is not None]
        extra = np.stack([positions[:, i] + world[:, i] @ offset for i, offset in tips], axis=1) \
            if tips else np.empty((n_frames, 0, 3))
        positions = np.concatenate([positions, extra], axis=1)
        names += [f"{layout[i].Name}.end" for i, _ in tips]
        parents += [i for i, _ in tips]
    if not np.isfinite(positions).all():
        raise MlctError(f"{path}: the motion contains NaN or inf values")
    return BvhClip(joint_names=tuple(names), parents=tuple(parents),
                   positions=positions, frame_time=float(container.FrameTime))
