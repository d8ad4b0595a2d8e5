"""CMU's own motion-capture format: an ASF skeleton (bones with a rest direction, a length, an
axis frame and the rotations they may take) and AMC frames (each bone's rotations in degrees,
the root's translation too), read into world positions per frame.

Forward kinematics as the format (Acclaim's, as CMU publishes it) defines it: a bone's local
rotation is C M C^-1, where C is its axis frame (Euler angles, the `axis` line's order) and M
its frame's rotation (its dofs, applied in the order x, y, z about the axis frame); a bone's
world rotation is its parent's times its local one, and its end lies at its start plus the world
rotation of its rest direction times its length. The root's frame comes from its own order and
axis lines. Joints are named after bones and placed at the bone's START (the parent's end), as
the BVH conversions of CMU's bones are (a BVH joint sits where its bone begins), so one joint
map serves both; the root is at its translation. Units are the ASF's (CMU's take 0.45 to
inches): a corpus importer scales by the legs.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mlct.errors import MlctError

AMC_FPS = 120.0  # CMU captured at 120 frames a second; the AMC files do not say it


@dataclass(frozen=True)
class Bone:
    name: str
    direction: np.ndarray  # (3,) unit, world axes at rest
    length: float
    axis: np.ndarray  # (3, 3) C: the bone's axis frame
    dofs: tuple[str, ...]  # e.g. ("rx", "rz")


@dataclass(frozen=True)
class AsfSkeleton:
    bones: dict[str, Bone]  # the root included, its direction zero
    parents: dict[str, str]  # bone -> parent bone
    order: tuple[str, ...]  # parents first
    root_order: tuple[str, ...]  # e.g. ("TX", "TY", "TZ", "RX", "RY", "RZ")
    root_axis: np.ndarray


def _rotation(axis: str, degrees: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation about x, y or z by `degrees`."""
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    rows = {"x": ((one, zero, zero), (zero, c, -s), (zero, s, c)),
            "y": ((c, zero, s), (zero, one, zero), (-s, zero, c)),
            "z": ((c, -s, zero), (s, c, zero), (zero, zero, one))}[axis]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def euler(angles: np.ndarray, order: str) -> np.ndarray:
    """(..., 3, 3) from (..., 3) angles in degrees about x, y, z, applied in `order` (the first
    letter first: 'XYZ' is Rz Ry Rx)."""
    angles = np.asarray(angles, dtype=np.float64)
    out = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for letter in order.lower():
        out = _rotation(letter, angles[..., "xyz".index(letter)]) @ out
    return out


def read_asf(path: str | os.PathLike) -> AsfSkeleton:
    """Parse an ASF file; a one-line MlctError naming what is missing otherwise."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as error:
        raise MlctError(f"{path}: cannot read ({error.strerror})") from None
    section, bones, parents, order = "", {}, {}, []
    root_order, root_axis = ("TX", "TY", "TZ", "RX", "RY", "RZ"), "XYZ"
    current: dict = {}
    for raw in lines:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith(":"):
            section = line.split()[0][1:]
            continue
        words = line.split()
        if section == "root":
            if words[0] == "order":
                root_order = tuple(w.upper() for w in words[1:])
            elif words[0] == "axis":
                root_axis = words[1]
        elif section == "bonedata":
            if words[0] == "begin":
                current = {"dofs": ()}
            elif words[0] == "end":
                axis = euler(np.array([float(v) for v in current["axis"][:3]]),
                             current["axis"][3])
                bones[current["name"]] = Bone(current["name"], current["direction"],
                                              current["length"], axis, current["dofs"])
            elif words[0] == "name":
                current["name"] = words[1]
            elif words[0] == "direction":
                current["direction"] = np.array([float(v) for v in words[1:4]])
            elif words[0] == "length":
                current["length"] = float(words[1])
            elif words[0] == "axis":
                current["axis"] = words[1:5]
            elif words[0] == "dof":
                current["dofs"] = tuple(w.lower() for w in words[1:])
        elif section == "hierarchy" and words[0] not in ("begin", "end"):
            for child in words[1:]:
                parents[child] = words[0]
    if not bones or not parents:
        raise MlctError(f"{path}: not an ASF skeleton (no :bonedata or :hierarchy)")
    bones["root"] = Bone("root", np.zeros(3), 0.0, euler(np.zeros(3), root_axis), ())
    seen = {"root"}
    while len(order) < len(parents):
        grown = [c for c, p in parents.items() if p in seen and c not in seen]
        if not grown:
            raise MlctError(f"{path}: its hierarchy does not reach every bone from the root")
        order += grown
        seen.update(grown)
    missing = [b for b in order if b not in bones]
    if missing:
        raise MlctError(f"{path}: the hierarchy names bones it does not define: "
                        f"{', '.join(missing)}")
    return AsfSkeleton(bones, parents, tuple(order), root_order, bones["root"].axis)


@dataclass(frozen=True)
class AmcClip:
    """An AMC take read back: joints named after bones (at each bone's start) and the root."""

    joint_names: tuple[str, ...]
    positions: np.ndarray  # (T, N, 3), the ASF's units
    fps: float


def _frames(path: Path) -> list[dict[str, list[float]]]:
    frames: list[dict[str, list[float]]] = []
    for raw in path.read_text(encoding="utf-8", errors="replace").splitlines():
        line = raw.strip()
        if not line or line.startswith(("#", ":")):
            continue
        words = line.split()
        if len(words) == 1 and words[0].isdigit():
            frames.append({})
        elif frames:
            try:
                frames[-1][words[0]] = [float(v) for v in words[1:]]
            except ValueError:
                raise MlctError(f"{path}: frame {len(frames)}: not numbers: {line}") from None
    if not frames:
        raise MlctError(f"{path}: no frames (an AMC file numbers each frame on its own line)")
    return frames


def read_amc(path: str | os.PathLike, asf: str | os.PathLike | None = None) -> AmcClip:
    """World positions of every bone's start and the root, per frame, at 120 fps. `asf`
    defaults to the subject's skeleton beside the take: SS_TT.amc next to SS.asf."""
    path = Path(path)
    if asf is None:
        asf = path.with_name(path.stem.split("_")[0] + ".asf")
    skeleton = read_asf(asf)
    frames = _frames(path)
    n = len(frames)

    def values(bone: str) -> np.ndarray:
        try:
            return np.array([f[bone] for f in frames])
        except KeyError:
            raise MlctError(f"{path}: a frame has no values for {bone}") from None

    root = values("root")
    channels = {c: root[:, i] for i, c in enumerate(skeleton.root_order)}
    start = np.stack([channels.get(f"T{a}", np.zeros(n)) for a in "XYZ"], axis=-1)
    rotation = {"root": skeleton.root_axis @ euler(
        np.stack([channels.get(f"R{a}", np.zeros(n)) for a in "XYZ"], axis=-1),
        "".join(c[1] for c in skeleton.root_order if c.startswith("R")) or "XYZ")
        @ skeleton.root_axis.T}
    end = {"root": start}
    begin = {"root": start}
    for name in skeleton.order:
        bone, parent = skeleton.bones[name], skeleton.parents[name]
        angles = np.zeros((n, 3))
        if bone.dofs:
            given = values(name)
            for i, dof in enumerate(bone.dofs):
                if dof.startswith("r"):
                    angles[:, "xyz".index(dof[1])] = given[:, i]
        local = bone.axis @ euler(angles, "XYZ") @ bone.axis.T
        rotation[name] = rotation[parent] @ local
        begin[name] = end[parent]
        end[name] = end[parent] + np.einsum("tij,j->ti", rotation[name],
                                            bone.direction * bone.length)
    names = ("root",) + skeleton.order
    positions = np.stack([begin[b] for b in names], axis=1)
    if not np.isfinite(positions).all():
        raise MlctError(f"{path}: the motion contains NaN or inf values")
    return AmcClip(joint_names=names, positions=positions, fps=AMC_FPS)
