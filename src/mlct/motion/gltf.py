"""glTF 2.0 binary (.glb) and VRM Animation (.vrma) export, and a reader to check them.

Both hold the shared rotation fit (rigfit.py) as a glTF animation clip on a node hierarchy:
one node per joint, named by the rig (rigs.py) or the skeleton, its rest translation the bone's
offset in the rest pose and no rest rotation; the clip keys every joint's rotation and the
root's translation at every frame (LINEAR, times in seconds from 0). glTF is y up, metres and
facing +Z by its specification, mlct's own frame, so a rig preset changes names and rest pose
only.

- .glb: also a skinned humanoid, a capsule per bone (rigidly bound to the joint that turns it)
  and a ball at each end joint (head, hands, toes), with the skin's joints and inverse bind
  matrices: three.js GLTFLoader, Blender's glTF importer, Unity (glTFast) and Unreal (its glTF
  importer) play it as it is.
- .vrma: the VRMC_vrm_animation 1.0 extension maps each VRM humanoid bone to its node, in a
  T-pose rest as VRM 1.0 asks; no mesh (a VRM animation moves someone else's avatar).

Written with pygltflib (the `export` extra); `read_gltf` parses a file back with it and computes
every node's world position per frame, independently of the writer's fit.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.io import write_bytes
from mlct.motion.rotations import matrix_to_quat, quat_to_matrix
from mlct.motion.rigfit import RigFit, fit_rig
from mlct.motion.rigs import Rig, get_rig
from mlct.motion.skeleton import Skeleton

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
CAPSULE_SEGMENTS, CAPSULE_RINGS = 12, 4  # around, and per half-sphere cap
BODY_COLOUR = [0.55, 0.62, 0.78, 1.0]
VRMA_EXTENSION = "VRMC_vrm_animation"
PER_METRE = {"m": 1.0, "mm": 1000.0}


def _pygltflib():
    try:
        import pygltflib
    except ImportError:
        raise MlctError("glTF/VRMA export needs pygltflib: pip install 'mlct[export]'") from None
    return pygltflib


def fit_for_gltf(joints: np.ndarray, skeleton: Skeleton, fps: float,
                 rig: Rig | None) -> tuple[RigFit, tuple[str, ...]]:
    """The rig fit in metres, and the joint names of the file."""
    fit = fit_rig(joints, skeleton, None if rig is None else rig.rest_directions, fps=fps)
    scale = 1.0 / PER_METRE[skeleton.unit]
    fit = RigFit(fit.parents, fit.order, fit.offsets * scale, fit.root * scale, fit.local,
                 fit.positions * scale)
    return fit, (skeleton.joint_names if rig is None else rig.joint_names)


class _Buffer:
    """One binary buffer, filled view by view (4-byte aligned), with accessors over it."""

    def __init__(self, gltf) -> None:
        self.gltf, self.data = gltf, bytearray()

    def add(self, array: np.ndarray, kind: str, component: int, target: int | None = None,
            bounds: bool = False) -> int:
        lib = _pygltflib()
        dtype = {FLOAT: np.float32, UNSIGNED_SHORT: np.uint16, UNSIGNED_INT: np.uint32}[component]
        array = np.ascontiguousarray(array, dtype=dtype)
        self.data.extend(b"\0" * (-len(self.data) % 4))
        view = lib.BufferView(buffer=0, byteOffset=len(self.data), byteLength=array.nbytes,
                              target=target)
        self.data.extend(array.tobytes())
        self.gltf.bufferViews.append(view)
        flat = array.reshape(len(array), -1)
        accessor = lib.Accessor(bufferView=len(self.gltf.bufferViews) - 1, componentType=component,
                                count=len(array), type=kind)
        if bounds:  # required for POSITION and animation inputs
            accessor.min, accessor.max = flat.min(0).tolist(), flat.max(0).tolist()
        self.gltf.accessors.append(accessor)
        return len(self.gltf.accessors) - 1


def _capsule(start: np.ndarray, end: np.ndarray, radius: float) -> tuple[np.ndarray, ...]:
    """Vertices, normals and triangles of a capsule around the segment start -> end."""
    axis = end - start
    length = float(np.linalg.norm(axis))
    y = axis / length if length > 1e-9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(y, [0.0, 0.0, 1.0] if abs(y[2]) < 0.9 else [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    # Rings from the bottom pole to the top one: a half-sphere at each end of the segment.
    lat = np.concatenate([np.linspace(-np.pi / 2, 0, CAPSULE_RINGS + 1),
                          np.linspace(0, np.pi / 2, CAPSULE_RINGS + 1)])
    shift = np.repeat([0.0, length], CAPSULE_RINGS + 1)
    lon = np.linspace(0, 2 * np.pi, CAPSULE_SEGMENTS, endpoint=False)
    cos_lat, sin_lat = np.cos(lat)[:, None], np.sin(lat)[:, None]
    normal_local = np.stack([cos_lat * np.cos(lon), np.broadcast_to(sin_lat, (len(lat), len(lon))),
                             cos_lat * np.sin(lon)], -1)  # (rings, segments, 3)
    basis = np.stack([x, y, z])  # rows: local axes in world
    normals = normal_local.reshape(-1, 3) @ basis
    centres = start + shift[:, None, None] * y
    vertices = (centres + radius * normal_local @ basis).reshape(-1, 3)
    triangles = []
    n_rings, n_seg = len(lat), len(lon)
    for r in range(n_rings - 1):
        for s in range(n_seg):
            a, b = r * n_seg + s, r * n_seg + (s + 1) % n_seg
            c, d = a + n_seg, b + n_seg
            triangles += [(a, c, b), (b, c, d)]  # counter-clockwise seen from outside
    return vertices, normals, np.array(triangles)


def _body_mesh(rest: np.ndarray, parents: tuple[int, ...], lengths: np.ndarray):
    """A capsule per bone on its parent joint, a ball on each end joint: vertices, normals,
    triangles and the joint each vertex follows."""
    children = {p for p in parents if p >= 0}
    parts = []
    for joint, parent in enumerate(parents):
        if parent >= 0:  # metres: limbs 2-5 cm thick
            radius = float(np.clip(0.15 * lengths[joint], 0.02, 0.05))
            parts.append((_capsule(rest[parent], rest[joint], radius), parent))
        if joint not in children:  # head, hands, toes
            radius = float(np.clip(0.6 * lengths[joint], 0.03, 0.06))
            parts.append((_capsule(rest[joint], rest[joint], radius), joint))
    vertices, normals, triangles, owners, count = [], [], [], [], 0
    for (v, n, t), owner in parts:
        vertices.append(v)
        normals.append(n)
        triangles.append(t + count)
        owners.append(np.full(len(v), owner))
        count += len(v)
    return (np.concatenate(vertices), np.concatenate(normals), np.concatenate(triangles),
            np.concatenate(owners))


def gltf_document(fit: RigFit, names: tuple[str, ...], fps: float, mesh: bool = True,
                  human_bones: dict[str, str] | None = None):
    """The pygltflib.GLTF2 of a fit in metres (module doc); human_bones: VRM bone -> joint name
    for the VRMC_vrm_animation extension."""
    lib = _pygltflib()
    n_frames, n_joints = fit.local.shape[:2]
    gltf = lib.GLTF2(asset=lib.Asset(version="2.0", generator="mlct"))
    gltf.buffers.append(lib.Buffer())
    buffer = _Buffer(gltf)
    children: list[list[int]] = [[] for _ in range(n_joints)]
    for joint, parent in enumerate(fit.parents):
        if parent >= 0:
            children[parent].append(joint)
    # Rest pose: identity rotations, the root over the floor at the rest pose's leg height.
    rest = np.zeros((n_joints, 3))
    for joint in fit.order[1:]:
        rest[joint] = rest[fit.parents[joint]] + fit.offsets[joint]
    rest_root = np.array([0.0, -rest[:, 1].min(), 0.0])
    rest += rest_root
    for joint in range(n_joints):
        translation = rest_root if fit.parents[joint] < 0 else fit.offsets[joint]
        gltf.nodes.append(lib.Node(name=names[joint], translation=translation.tolist(),
                                   children=children[joint] or []))
    root = fit.order[0]
    scene_nodes = [root]
    if mesh:
        vertices, normals, triangles, owners = _body_mesh(rest, fit.parents, fit.lengths)
        joints_attr = np.zeros((len(vertices), 4), np.uint16)
        joints_attr[:, 0] = owners
        weights = np.zeros((len(vertices), 4))
        weights[:, 0] = 1.0
        attributes = lib.Attributes(
            POSITION=buffer.add(vertices, "VEC3", FLOAT, ARRAY_BUFFER, bounds=True),
            NORMAL=buffer.add(normals, "VEC3", FLOAT, ARRAY_BUFFER),
            JOINTS_0=buffer.add(joints_attr, "VEC4", UNSIGNED_SHORT, ARRAY_BUFFER),
            WEIGHTS_0=buffer.add(weights, "VEC4", FLOAT, ARRAY_BUFFER))
        indices = buffer.add(triangles.reshape(-1), "SCALAR", UNSIGNED_INT, ELEMENT_ARRAY_BUFFER)
        gltf.materials.append(lib.Material(name="body", pbrMetallicRoughness=lib.PbrMetallicRoughness(
            baseColorFactor=BODY_COLOUR, metallicFactor=0.0, roughnessFactor=0.8)))
        gltf.meshes.append(lib.Mesh(name="body", primitives=[lib.Primitive(
            attributes=attributes, indices=indices, material=0)]))
        inverse_bind = np.tile(np.eye(4), (n_joints, 1, 1))
        inverse_bind[:, :3, 3] = -rest  # rest world transforms are pure translations
        bind = buffer.add(np.swapaxes(inverse_bind, 1, 2).reshape(n_joints, 16), "MAT4", FLOAT)
        gltf.skins.append(lib.Skin(name="armature", joints=list(range(n_joints)), skeleton=root,
                                   inverseBindMatrices=bind))
        gltf.nodes.append(lib.Node(name="body", mesh=0, skin=0))
        scene_nodes.append(len(gltf.nodes) - 1)
    gltf.scenes.append(lib.Scene(name="mlct", nodes=scene_nodes))
    gltf.scene = 0

    times = buffer.add(np.arange(n_frames) / float(fps), "SCALAR", FLOAT, bounds=True)
    quats = matrix_to_quat(fit.local)[..., [1, 2, 3, 0]]  # xyzw
    quats *= np.where(quats[..., 3:] < 0, -1.0, 1.0)  # one hemisphere per key...
    for t in range(1, n_frames):  # ...then continuous, so LINEAR never takes the long way
        flip = np.sum(quats[t] * quats[t - 1], axis=-1) < 0
        quats[t, flip] *= -1
    samplers, channels = [], []
    for joint in range(n_joints):
        samplers.append(lib.AnimationSampler(input=times, interpolation="LINEAR",
                                             output=buffer.add(quats[:, joint], "VEC4", FLOAT)))
        channels.append(lib.AnimationChannel(sampler=len(samplers) - 1, target=lib.AnimationChannelTarget(
            node=joint, path="rotation")))
    samplers.append(lib.AnimationSampler(input=times, interpolation="LINEAR",
                                         output=buffer.add(fit.root, "VEC3", FLOAT)))
    channels.append(lib.AnimationChannel(sampler=len(samplers) - 1, target=lib.AnimationChannelTarget(
        node=root, path="translation")))
    gltf.animations.append(lib.Animation(name="motion", samplers=samplers, channels=channels))
    if human_bones is not None:
        index = {name: i for i, name in enumerate(names)}
        gltf.extensionsUsed = [VRMA_EXTENSION]
        gltf.extensions = {VRMA_EXTENSION: {"specVersion": "1.0", "humanoid": {"humanBones": {
            bone: {"node": index[joint]} for bone, joint in human_bones.items()}}}}
    gltf.buffers[0].byteLength = len(buffer.data)
    gltf.set_binary_blob(bytes(buffer.data))
    return gltf


def _check_fps(fps: float) -> float:
    try:
        rate = float(fps)
    except (TypeError, ValueError):
        rate = float("nan")
    if not (np.isfinite(rate) and rate > 0):
        raise MlctError(f"glTF export needs a positive frame rate, got {fps!r}")
    return rate


def glb_bytes(joints: np.ndarray, skeleton: Skeleton, fps: float,
              rig: str | Rig | None = None) -> bytes:
    """A .glb of (T, J, 3) joints: skinned humanoid and animation (module doc)."""
    rate = _check_fps(fps)
    fit, names = fit_for_gltf(joints, skeleton, rate, get_rig(rig, skeleton))
    return b"".join(gltf_document(fit, names, rate).save_to_bytes())


def vrma_bytes(joints: np.ndarray, skeleton: Skeleton, fps: float) -> bytes:
    """A .vrma (VRM Animation 1.0) of (T, J, 3) humanml3d joints, in VRM's T-pose rest."""
    rate = _check_fps(fps)
    vrm = get_rig("vrm", skeleton)
    assert vrm is not None
    fit, names = fit_for_gltf(joints, skeleton, rate, vrm)
    bones = {name: name for name in names}  # the vrm preset's names are VRM's bone names
    return b"".join(gltf_document(fit, names, rate, mesh=False, human_bones=bones).save_to_bytes())


def write_glb(path: str | os.PathLike, joints: np.ndarray, skeleton: Skeleton, fps: float,
              rig: str | Rig | None = None) -> None:
    write_bytes(path, glb_bytes(joints, skeleton, fps, rig))


def write_vrma(path: str | os.PathLike, joints: np.ndarray, skeleton: Skeleton,
               fps: float) -> None:
    write_bytes(path, vrma_bytes(joints, skeleton, fps))


@dataclass(frozen=True)
class GltfClip:
    """A glTF file read back: its joint nodes and their world positions at the key times."""

    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    positions: np.ndarray  # (T, N, 3) metres
    times: np.ndarray  # (T,) seconds
    extensions: dict


def _accessor(gltf, blob: bytes, index: int) -> np.ndarray:
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[accessor.type]
    dtype = {FLOAT: np.float32, UNSIGNED_SHORT: np.uint16, UNSIGNED_INT: np.uint32}[
        accessor.componentType]
    start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
    return np.frombuffer(blob, dtype, accessor.count * width, start).reshape(accessor.count, width)


def read_gltf(path: str | os.PathLike) -> GltfClip:
    """Parse a .glb/.vrma (pygltflib) and compute every non-mesh node's world position at each
    key time of its first animation: node translation/rotation, overridden by the channels."""
    lib = _pygltflib()
    path = Path(path)
    try:
        gltf = lib.GLTF2.load_binary(str(path))
    except Exception as error:  # pygltflib raises whatever its parser meets
        raise MlctError(f"{path}: not a readable glTF binary ({first_line(error)})") from None
    if gltf is None or not gltf.animations:
        raise MlctError(f"{path}: no glTF animation in it")
    blob = gltf.binary_blob()
    joints = [i for i, node in enumerate(gltf.nodes) if node.mesh is None]
    index = {node: i for i, node in enumerate(joints)}
    parents = [-1] * len(joints)
    for node in joints:
        for child in gltf.nodes[node].children or []:
            parents[index[child]] = index[node]
    animation = gltf.animations[0]
    times = _accessor(gltf, blob, animation.samplers[0].input)[:, 0].astype(np.float64)
    n_frames = len(times)
    translation = np.array([gltf.nodes[n].translation or [0.0, 0.0, 0.0] for n in joints], float)
    rotation = np.array([gltf.nodes[n].rotation or [0.0, 0.0, 0.0, 1.0] for n in joints], float)
    translation = np.repeat(translation[None], n_frames, 0)
    rotation = np.repeat(rotation[None], n_frames, 0)
    for channel in animation.channels:
        sampler = animation.samplers[channel.sampler]
        values = _accessor(gltf, blob, sampler.output).astype(np.float64)
        if len(values) != n_frames:
            raise MlctError(f"{path}: animation channels with different key counts")
        target = index[channel.target.node]
        if channel.target.path == "rotation":
            rotation[:, target] = values
        elif channel.target.path == "translation":
            translation[:, target] = values
    rotation /= np.linalg.norm(rotation, axis=-1, keepdims=True)
    matrices = quat_to_matrix(rotation[..., [3, 0, 1, 2]])  # glTF: xyzw
    positions = np.empty((n_frames, len(joints), 3))
    world = np.empty((n_frames, len(joints), 3, 3))
    done: set[int] = set()  # glTF lists nodes in no order: each after its parent
    while len(done) < len(joints):
        for i in range(len(joints)):
            if i in done or (parents[i] >= 0 and parents[i] not in done):
                continue
            if parents[i] < 0:
                positions[:, i], world[:, i] = translation[:, i], matrices[:, i]
            else:
                p = parents[i]
                positions[:, i] = positions[:, p] + np.einsum("tij,tj->ti", world[:, p],
                                                              translation[:, i])
                world[:, i] = world[:, p] @ matrices[:, i]
            done.add(i)
    return GltfClip(tuple(gltf.nodes[n].name for n in joints), tuple(parents), positions, times,
                    dict(gltf.extensions or {}))
