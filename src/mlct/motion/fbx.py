"""FBX export: the shared rotation fit as a skeleton and one animation take, binary FBX 7.4.

Written without Autodesk's SDK (the container is fbx_binary.py). What the file holds:

- GlobalSettings: the axis system and unit. Without a rig: Y up, facing +Z, the character's
  left on +X (mlct's frame, Maya's and Mixamo's); a preset's axes otherwise, stated so that an
  importer turns the scene into its own (rigs.py: unreal is Z up, facing +Y). The unit is
  always the centimetre (UnitScaleFactor 1), FBX's own: importers scale it to theirs. TimeMode
  names the frame rate when FBX has a mode for it, else "custom" with CustomFrameRate.
- Objects: a Null "Armature" at the origin, and under it one LimbNode Model per joint (with its
  NodeAttribute), named by the rig or the skeleton, parented as the skeleton is. A Model's
  Lcl Translation is its bone's rest offset, its Lcl Rotation 0: the rest pose is the rig's
  (T- or A-pose, or the skeleton's own standing pose) standing on the floor at the origin, its
  lowest joint at height 0; a BindPose records it (the world matrix of every node).
- One AnimationStack and AnimationLayer: every joint's Lcl Rotation and the root's Lcl
  Translation keyed at every frame (an AnimationCurveNode each, an AnimationCurve per axis),
  linear keys, times in FBX ticks (KTIME_PER_SECOND) from 0, so the last key is at
  (T - 1) / fps seconds. Rotations are Euler angles in degrees, RotationOrder eEulerXYZ (the
  FBX default, stated on every Model): the local rotation is Rz(z) Ry(y) Rx(x), X applied first;
  unwrapped over time so no angle jumps by 360.

The rest offsets and per-frame local rotations are the BVH export's (motion/rigfit.py, the
axes of bvh.bvh_frame), so the FBX and the BVH of one motion move the same skeleton the same way;
only the Euler order differs (BVH: ZXY) and the unit stays centimetres for metre rigs.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from mlct.errors import MlctError
from mlct.io import write_bytes
from mlct.motion.bvh import TO_CENTIMETRES, bvh_frame
from mlct.motion.fbx_binary import CREATION_TIME, FILE_ID, Long, Node, encode, properties
from mlct.motion.rigfit import check_joints, fit_rig
from mlct.motion.rigs import Rig, get_rig
from mlct.motion.skeleton import Skeleton

VERSION = 7400
KTIME_PER_SECOND = 46186158000  # FBX 7.x time unit (ticks per second)
TIME_MODES = {120.0: 1, 100.0: 2, 60.0: 3, 50.0: 4, 48.0: 5, 30.0: 6, 25.0: 10, 24.0: 11,
              96.0: 15, 72.0: 16}  # FBX's named frame rates; any other is 14, custom
CUSTOM_TIME_MODE = 14
EULER_XYZ = 0  # RotationOrder eEulerXYZ
ARMATURE = "Armature"  # the Null above the root joint: Blender makes its armature object of it
TAKE = "motion"  # the animation stack's (and Blender's action's) name
# Key attributes, one set shared by every key of a curve (KeyAttrRefCount: all of them): linear
# interpolation (0x4) with the auto and generic tangent bits FBX writers set, and four data
# floats (the tangents' slopes and weights: unused by linear keys).
KEY_FLAGS = 0x4 | 0x100 | 0x2000 | 0x4000
KEY_DATA = np.array([0.0, 0.0, 9.419963346924634e-30, 0.0], dtype=np.float32)
KEY_VERSION = 4008
MODEL_VERSION = 232


@dataclass(frozen=True)
class FbxPose:
    """A motion fitted to a rigid skeleton in the file's frame, centimetres and degrees."""

    names: tuple[str, ...]
    parents: tuple[int, ...]  # -1 for the root
    order: tuple[int, ...]  # depth first from the root
    offsets: np.ndarray  # (J, 3) rest offsets from the parent (root: its rest position)
    root: np.ndarray  # (T, 3) root positions
    euler: np.ndarray  # (T, J, 3) local rotations, degrees, X Y Z of eEulerXYZ
    axes: np.ndarray  # (3, 3) mlct's frame -> the file's


def euler_xyz_degrees(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 3) angles (x, y, z) in degrees with
    m = Rz(z) Ry(y) Rx(x), y in [-90, 90] (FBX's eEulerXYZ).

    From the product written out: m[2, 0] = -sin y, (m[2, 1], m[2, 2]) = cos y (sin x, cos x),
    (m[1, 0], m[0, 0]) = cos y (sin z, cos z). At y = +-90 degrees only x -+ z is defined:
    z is 0 there and x comes from (m[1, 2], m[1, 1]) = (-sin x, cos x)."""
    cos_y = np.hypot(m[..., 0, 0], m[..., 1, 0])
    y = np.arctan2(-m[..., 2, 0], cos_y)
    locked = cos_y < 1e-7
    x = np.where(locked, np.arctan2(-m[..., 1, 2], m[..., 1, 1]),
                 np.arctan2(m[..., 2, 1], m[..., 2, 2]))
    z = np.where(locked, 0.0, np.arctan2(m[..., 1, 0], m[..., 0, 0]))
    return np.degrees(np.stack([x, y, z], axis=-1))


def fit_fbx(joints: np.ndarray, skeleton: Skeleton, rig: Rig | None, fps: float) -> FbxPose:
    """Fit (T, J, 3) joints (skeleton units) to the rig's skeleton, in the file's frame."""
    fit = fit_rig(check_joints(joints, skeleton, "FBX export"), skeleton,
                  None if rig is None else rig.rest_directions, fps=fps)
    axes, _ = bvh_frame(skeleton, rig)
    scale = TO_CENTIMETRES[skeleton.unit]
    rest = np.zeros_like(fit.offsets)  # rest positions, mlct's frame: rotations all identity
    for joint in fit.order[1:]:
        rest[joint] = rest[fit.parents[joint]] + fit.offsets[joint]
    offsets = fit.offsets.copy()
    offsets[0] = [0.0, -rest[:, 1].min(), 0.0]  # the rest pose stands on the floor
    local = axes @ fit.local @ axes.T  # the same turns, seen in the file's frame
    return FbxPose(names=skeleton.joint_names if rig is None else rig.joint_names,
                   parents=fit.parents, order=fit.order, offsets=offsets @ axes.T * scale,
                   root=fit.root @ axes.T * scale,
                   euler=np.unwrap(euler_xyz_degrees(local), period=360.0, axis=0), axes=axes)


def axis_system(axes: np.ndarray) -> dict[str, int]:
    """GlobalSettings' axis entries for a frame: the file's axis (0, 1, 2) and sign that mlct's
    up (+y), front (the way the character faces, +z) and coord (its left, +x) lie along."""
    out = {}
    for key, column in (("Up", 1), ("Front", 2), ("Coord", 0)):
        image = axes[:, column]
        index = int(np.argmax(np.abs(image)))
        out[f"{key}Axis"], out[f"{key}AxisSign"] = index, int(np.sign(image[index]))
    return out


def _ktime(seconds: float) -> Long:
    return Long(round(seconds * KTIME_PER_SECOND))


def _p(name: str, kind: str, label: str, flags: str, *values) -> tuple:
    return (name, kind, label, flags, *values)


def _header(version: int) -> list[Node]:
    stamp = Node("CreationTimeStamp", children=[
        Node(k, [v]) for k, v in (("Version", 1000), ("Year", 1970), ("Month", 1), ("Day", 1),
                                  ("Hour", 10), ("Minute", 0), ("Second", 0),
                                  ("Millisecond", 0))])  # CREATION_TIME: see fbx_binary
    extension = Node("FBXHeaderExtension", children=[
        Node("FBXHeaderVersion", [1003]), Node("FBXVersion", [version]),
        Node("EncryptionType", [0]), stamp, Node("Creator", ["mlct"])])
    return [extension, Node("FileId", [FILE_ID]), Node("CreationTime", [CREATION_TIME]),
            Node("Creator", ["mlct"])]


def _global_settings(axes: np.ndarray, fps: float, stop: Long) -> Node:
    mode = next((m for rate, m in TIME_MODES.items() if abs(rate - fps) < 1e-6),
                CUSTOM_TIME_MODE)
    entries = [_p(name, "int", "Integer", "", value)
               for name, value in axis_system(axes).items()]
    entries += [_p("OriginalUpAxis", "int", "Integer", "", -1),
                _p("OriginalUpAxisSign", "int", "Integer", "", 1),
                _p("UnitScaleFactor", "double", "Number", "", 1.0),  # centimetres
                _p("OriginalUnitScaleFactor", "double", "Number", "", 1.0),
                _p("TimeMode", "enum", "", "", mode),
                _p("TimeSpanStart", "KTime", "Time", "", Long(0)),
                _p("TimeSpanStop", "KTime", "Time", "", stop),
                _p("CustomFrameRate", "double", "Number", "", float(fps))]
    return Node("GlobalSettings", children=[Node("Version", [1000]), properties(*entries)])


def _model(uid: int, name: str, kind: str, translation: np.ndarray, animated: bool) -> Node:
    flags = "A+" if animated else "A"
    entries = [_p("RotationOrder", "enum", "", "", EULER_XYZ),
               _p("RotationActive", "bool", "", "", 1),
               _p("InheritType", "enum", "", "", 1),
               _p("DefaultAttributeIndex", "int", "Integer", "", 0),
               _p("Lcl Translation", "Lcl Translation", "", flags, *map(float, translation)),
               _p("Lcl Rotation", "Lcl Rotation", "", flags, 0.0, 0.0, 0.0),
               _p("Lcl Scaling", "Lcl Scaling", "", "A", 1.0, 1.0, 1.0)]
    return Node("Model", [Long(uid), f"{name}\x00\x01Model", kind], [
        Node("Version", [MODEL_VERSION]), properties(*entries), Node("Shading", [True]),
        Node("Culling", ["CullingOff"])])


def _curve(uid: int, times: np.ndarray, values: np.ndarray) -> Node:
    return Node("AnimationCurve", [Long(uid), "\x00\x01AnimCurve", ""], [
        Node("Default", [float(values[0])]), Node("KeyVer", [KEY_VERSION]),
        Node("KeyTime", [times]), Node("KeyValueFloat", [values.astype(np.float32)]),
        Node("KeyAttrFlags", [np.array([KEY_FLAGS], dtype=np.int32)]),
        Node("KeyAttrDataFloat", [KEY_DATA]),
        Node("KeyAttrRefCount", [np.array([len(times)], dtype=np.int32)])])


def fbx_nodes(pose: FbxPose, fps: float, version: int = VERSION) -> list[Node]:
    """The top-level records of the file of a fitted pose (module doc)."""
    n_frames, n_joints = pose.euler.shape[:2]
    times = np.round(np.arange(n_frames) * (KTIME_PER_SECOND / fps)).astype(np.int64)
    stop = Long(int(times[-1]))
    ids = iter(range(1_000_000, 2**62))
    objects, links = Node("Objects"), Node("Connections")
    counts: dict[str, int] = {}

    def obj(node: Node) -> int:
        objects.children.append(node)
        counts[node.name] = counts.get(node.name, 0) + 1
        return int(node.values[0])

    def link(child: int, parent: int, prop: str | None = None) -> None:
        links.add("C", *(["OO", Long(child), Long(parent)] if prop is None
                         else ["OP", Long(child), Long(parent), prop]))

    armature = obj(_model(next(ids), ARMATURE, "Null", np.zeros(3), False))
    link(obj(Node("NodeAttribute", [Long(next(ids)), f"{ARMATURE}\x00\x01NodeAttribute",
                                    "Null"], [Node("TypeFlags", ["Null"])])), armature)
    link(armature, 0)
    bones: dict[int, int] = {}
    for joint in pose.order:
        name = pose.names[joint]
        bones[joint] = obj(_model(next(ids), name, "LimbNode", pose.offsets[joint], True))
        link(obj(Node("NodeAttribute", [Long(next(ids)), f"{name}\x00\x01NodeAttribute",
                                        "LimbNode"], [Node("TypeFlags", ["Skeleton"])])),
             bones[joint])
        parent = pose.parents[joint]
        link(bones[joint], armature if parent < 0 else bones[parent])

    # The bind pose: each node's rest world matrix (column-major, translation last).
    obj(Node("Pose", [Long(next(ids)), "BindPose\x00\x01Pose", "BindPose"], [
        Node("Type", ["BindPose"]), Node("Version", [100]),
        Node("NbPoseNodes", [n_joints + 1])]))
    bind = objects.children[-1]
    world = {-1: np.zeros(3)}
    for uid, joint in [(armature, -1)] + [(bones[j], j) for j in pose.order]:
        if joint >= 0:
            world[joint] = world[pose.parents[joint]] + pose.offsets[joint]
        matrix = np.eye(4)
        matrix[3, :3] = world[joint]
        bind.add("PoseNode", children=[Node("Node", [Long(uid)]),
                                       Node("Matrix", [matrix.reshape(-1)])])

    stack = obj(Node("AnimationStack", [Long(next(ids)), f"{TAKE}\x00\x01AnimStack", ""], [
        properties(*[_p(k, "KTime", "Time", "", t) for k, t in (
            ("LocalStart", Long(0)), ("LocalStop", stop), ("ReferenceStart", Long(0)),
            ("ReferenceStop", stop))])]))
    layer = obj(Node("AnimationLayer", [Long(next(ids)), f"{TAKE}\x00\x01AnimLayer", ""]))
    link(layer, stack)
    channels = [(bones[j], "R", "Lcl Rotation", pose.euler[:, j]) for j in pose.order]
    channels.insert(0, (bones[pose.order[0]], "T", "Lcl Translation", pose.root))
    for model, short, prop, values in channels:
        curve_node = obj(Node("AnimationCurveNode",
                              [Long(next(ids)), f"{short}\x00\x01AnimCurveNode", ""],
                              [properties(*[_p(f"d|{axis}", "Number", "", "A",
                                               float(values[0, i]))
                                            for i, axis in enumerate("XYZ")])]))
        link(curve_node, layer)
        link(curve_node, model, prop)
        for i, axis in enumerate("XYZ"):
            link(obj(_curve(next(ids), times, values[:, i])), curve_node, f"d|{axis}")

    types = [Node("ObjectType", ["GlobalSettings"], [Node("Count", [1])])]
    types += [Node("ObjectType", [kind], [Node("Count", [n])]) for kind, n in counts.items()]
    definitions = Node("Definitions", children=[
        Node("Version", [100]), Node("Count", [sum(counts.values()) + 1]), *types])
    document = Node("Document", [Long(next(ids)), "Scene", "Scene"], [
        properties(_p("SourceObject", "object", "", ""),
                   _p("ActiveAnimStackName", "KString", "", "", TAKE)),
        Node("RootNode", [Long(0)])])
    takes = Node("Takes", children=[Node("Current", [TAKE]), Node("Take", [TAKE], [
        Node("FileName", [f"{TAKE}.tak"]), Node("LocalTime", [Long(0), stop]),
        Node("ReferenceTime", [Long(0), stop])])])
    return [*_header(version), _global_settings(pose.axes, fps, stop),
            Node("Documents", children=[Node("Count", [1]), document]), Node("References"),
            definitions, objects, links, takes]


def fbx_bytes(joints: np.ndarray, skeleton: Skeleton, fps: float,
              rig: str | os.PathLike | Rig | None = None, version: int = VERSION) -> bytes:
    """The binary FBX file of (T, J, 3) joint positions at `fps` (module doc)."""
    try:
        rate = float(fps)
    except (TypeError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise MlctError(f"FBX export needs a positive frame rate, got {fps!r}")
    pose = fit_fbx(joints, skeleton, get_rig(rig, skeleton), rate)
    return encode(fbx_nodes(pose, rate, version), version)


def write_fbx(path: str | os.PathLike, joints: np.ndarray, skeleton: Skeleton, fps: float,
              rig: str | os.PathLike | Rig | None = None) -> None:
    """Write (T, J, 3) joint positions as a binary FBX file at `fps`, atomically."""
    write_bytes(path, fbx_bytes(joints, skeleton, fps, rig))
