"""An independent binary-FBX reader for the export tests: it parses the bytes by the published
layout (not through mlct's writer), gathers the skeleton and its animation curves, and runs
forward kinematics by FBX's rules. Also a rigid test motion, which a rig file can hold exactly."""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mlct.motion.skeleton import Skeleton

HEADER = b"Kaydara FBX Binary  \x00\x1a\x00"
SCALARS = {b"C": "<B", b"Y": "<h", b"I": "<i", b"L": "<q", b"F": "<f", b"D": "<d"}
ARRAYS = {b"f": "<f4", b"d": "<f8", b"l": "<i8", b"i": "<i4", b"b": "u1"}


@dataclass
class Record:
    name: str
    values: list
    children: list[Record]
    compressed: list[bool]  # per value: a zlib'd array

    def first(self, name: str) -> Record:
        return next(c for c in self.children if c.name == name)

    def all(self, name: str) -> list[Record]:
        return [c for c in self.children if c.name == name]

    def props(self) -> dict[str, list]:
        """Properties70 as {name: values after the four metadata strings}."""
        return {p.values[0]: p.values[4:] for p in self.first("Properties70").children}


def parse(data: bytes) -> tuple[int, list[Record], bytes]:
    """(version, top-level records, the bytes after the closing null record)."""
    assert data[:len(HEADER)] == HEADER
    version = struct.unpack_from("<I", data, len(HEADER))[0]
    wide = version >= 7500
    pos, records = len(HEADER) + 4, []

    def read(pos: int) -> tuple[Record | None, int]:
        fmt = "<QQQB" if wide else "<IIIB"
        end, count, _, name_len = struct.unpack_from(fmt, data, pos)
        pos += struct.calcsize(fmt)
        if end == 0:
            return None, pos
        name = data[pos:pos + name_len].decode("ascii")
        pos += name_len
        values, compressed = [], []
        for _ in range(count):
            code = data[pos:pos + 1]
            pos += 1
            if code in SCALARS:
                (value,) = struct.unpack_from(SCALARS[code], data, pos)
                pos += struct.calcsize(SCALARS[code])
                compressed.append(False)
            elif code in (b"S", b"R"):
                (size,) = struct.unpack_from("<I", data, pos)
                raw = data[pos + 4:pos + 4 + size]
                value = raw.decode("utf-8") if code == b"S" else raw
                pos += 4 + size
                compressed.append(False)
            else:
                length, encoding, size = struct.unpack_from("<III", data, pos)
                raw = data[pos + 12:pos + 12 + size]
                pos += 12 + size
                raw = zlib.decompress(raw) if encoding == 1 else raw
                value = np.frombuffer(raw, dtype=ARRAYS[code])
                assert len(value) == length
                compressed.append(encoding == 1)
            values.append(value)
        children = []
        while pos < end:
            child, pos = read(pos)
            if child is None:
                break
            children.append(child)
        assert pos == end, f"record {name} ends at {pos}, says {end}"
        return Record(name, values, children, compressed), pos

    while True:
        record, pos = read(pos)
        if record is None:
            return version, records, data[pos:]
        records.append(record)


@dataclass
class FbxSkeleton:
    """The LimbNode skeleton of a file and its animation, in the file's frame and units."""

    settings: dict[str, list]
    names: list[str]
    parents: list[int]  # -1: the root joint (under the Null)
    rest: np.ndarray  # (J, 3) Lcl Translation of each Model
    times: np.ndarray  # (T,) key times, FBX ticks
    translation: np.ndarray  # (T, J, 3) Lcl Translation per frame
    rotation: np.ndarray  # (T, J, 3) Lcl Rotation per frame, degrees
    rotation_orders: list[int]
    records: list[Record]

    def positions(self) -> np.ndarray:
        """(T, J, 3) world positions: FBX's node transform T * R (eEulerXYZ) down the tree."""
        assert set(self.rotation_orders) == {0}  # eEulerXYZ: Rz Ry Rx
        n_frames, n_joints = self.rotation.shape[:2]
        local = Rotation.from_euler("xyz", self.rotation.reshape(-1, 3), degrees=True)
        local = local.as_matrix().reshape(n_frames, n_joints, 3, 3)
        world, pos = np.empty_like(local), np.empty((n_frames, n_joints, 3))
        done: set[int] = set()
        while len(done) < n_joints:
            for j in range(n_joints):
                parent = self.parents[j]
                if j in done or (parent >= 0 and parent not in done):
                    continue
                if parent < 0:
                    world[:, j], pos[:, j] = local[:, j], self.translation[:, j]
                else:
                    world[:, j] = world[:, parent] @ local[:, j]
                    pos[:, j] = pos[:, parent] + np.einsum("tij,tj->ti", world[:, parent],
                                                           self.translation[:, j])
                done.add(j)
        return pos


def read_skeleton(data: bytes) -> FbxSkeleton:
    _, records, _ = parse(data)
    top = {r.name: r for r in records}
    objects = {int(r.values[0]): r for r in top["Objects"].children}
    links = [c.values for c in top["Connections"].all("C")]
    parent_of = {int(v[1]): int(v[2]) for v in links if v[0] == "OO"}
    bones = [uid for uid, r in objects.items() if r.name == "Model" and r.values[2] == "LimbNode"]
    index = {uid: i for i, uid in enumerate(bones)}
    names = [objects[uid].values[1].split("\x00\x01")[0] for uid in bones]
    parents = [index.get(parent_of[uid], -1) for uid in bones]
    props = [objects[uid].props() for uid in bones]
    rest = np.array([p["Lcl Translation"] for p in props], dtype=np.float64)
    curves: dict[tuple[int, str, str], Record] = {}  # (model, property, axis) -> curve
    for v in links:
        if v[0] == "OP" and objects.get(int(v[1])) is not None and \
                objects[int(v[1])].name == "AnimationCurve":
            node = int(v[2])
            model, prop = next((int(w[2]), w[3]) for w in links
                               if w[0] == "OP" and int(w[1]) == node)
            curves[(model, prop, v[3])] = objects[int(v[1])]
    times = next(iter(curves.values())).first("KeyTime").values[0]
    n_frames = len(times)
    translation = np.broadcast_to(rest, (n_frames,) + rest.shape).copy()
    rotation = np.zeros_like(translation)
    for (model, prop, axis), curve in curves.items():
        assert np.array_equal(curve.first("KeyTime").values[0], times)
        values = curve.first("KeyValueFloat").values[0].astype(np.float64)
        target = translation if prop == "Lcl Translation" else rotation
        target[:, index[model], "XYZ".index(axis[-1])] = values
    orders = [int(p.get("RotationOrder", [0])[0]) for p in props]
    return FbxSkeleton(top["GlobalSettings"].props(), names, parents, rest, times, translation,
                       rotation, orders, records)


def rigid_joints(skeleton: Skeleton, n_frames: int, seed: int) -> np.ndarray:
    """(T, J, 3) a rigid skeleton moved as a rig file moves one: each joint turns its children
    together by smooth random local rotations, the root walks and turns about y."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_frames)[:, None]
    axes = rng.normal(size=(skeleton.n_joints, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = 0.6 * np.sin(2 * math.pi * (rng.uniform(0.5, 2.0, skeleton.n_joints) * t
                                         + rng.uniform(0, 1, skeleton.n_joints)))
    local = Rotation.from_rotvec((angles[..., None] * axes).reshape(-1, 3)).as_matrix()
    local = local.reshape(n_frames, skeleton.n_joints, 3, 3)
    local[:, 0] = Rotation.from_euler("y", math.pi * t).as_matrix()
    height = 0.9 * {"m": 1.0, "mm": 1000.0}[skeleton.unit]
    pos = np.empty((n_frames, skeleton.n_joints, 3))
    world = np.empty_like(local)
    pos[:, 0] = np.concatenate([t * height, np.full_like(t, height), t * height], axis=1)
    world[:, 0] = local[:, 0]
    for joint in range(1, skeleton.n_joints):  # parents come first on mlct's skeletons
        parent = skeleton.parents[joint]
        world[:, joint] = world[:, parent] @ local[:, joint]
        pos[:, joint] = pos[:, parent] + world[:, parent] @ skeleton.rest_offsets[joint]
    return pos
