"""The binary FBX container: a tree of named records with typed values, as bytes.

Blender's FBX importer reads binary FBX only (ASCII files it refuses), and Autodesk's SDK, which
Unity, Unreal and Maya read with, takes binary as well, so this is the one encoding mlct writes.
The layout, as documented publicly (the "FBX binary file format specification" that Blender's
developers published, and the readers that follow it):

- header: "Kaydara FBX Binary  " (two spaces), NUL, 0x1A, 0x00, then the version (uint32 LE);
- a node record: end offset (absolute position just past the record), number of values, the
  values' byte length, the name's length (uint8), the name, the values, the children; the
  three counts are uint32 before version 7500 and uint64 from it. A record with children ends
  them with a null record (the counts and name length all zero: 13 or 25 bytes). Readers also
  expect one after a record with neither values nor children, and AnimationStack and
  AnimationLayer records always carry one;
- a value: a type code, then C (bool, 1 byte), Y (int16), I (int32), L (int64), F (float32),
  D (float64), S (string) or R (raw bytes: uint32 length, then the bytes), or an array f, d, l,
  i, b: element count, encoding (0 plain, 1 zlib), byte length (uint32 each), the data;
- the top level is a list of records ended by a null record, then the footer (`_footer`).

Values are typed from Python's: bool C, `Long` L, other int I, float D, numpy.float32 F, str S,
bytes R, numpy arrays by dtype. Everything is little-endian.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

MAGIC = b"Kaydara FBX Binary  \x00\x1a\x00"
VERSIONS = (7400, 7500)  # 7.4 (32-bit counts) and 7.5 (64-bit): every current reader takes both
ARRAY_CODES = {np.dtype(np.float32): b"f", np.dtype(np.float64): b"d", np.dtype(np.int64): b"l",
               np.dtype(np.int32): b"i", np.dtype(np.bool_): b"b"}
COMPRESS_BYTES = 256  # arrays above this are zlib'd when that makes them smaller
ALWAYS_NULL_RECORD = frozenset({"AnimationStack", "AnimationLayer"})
# The file's identity, its creation time and the footer's first 16 bytes are tied together:
# Autodesk's SDK checks them against one another. These three are a matching set that readers
# accept (the values FBX writers without the SDK use, with the creation time held fixed).
FILE_ID = bytes.fromhex("28b32aebb624ccc2bfc8b02aa92bfcf1")
CREATION_TIME = "1970-01-01 10:00:00:000"
FOOTER_ID = bytes.fromhex("fabcab09d0c8d466b176fb831cf7267e")
FOOTER_MAGIC = bytes.fromhex("f85a8c6adef5d97eece90ce3758f290b")


class Long(int):
    """An int written as L (int64): object ids and times; a plain int is I (int32)."""


@dataclass
class Node:
    """One record: a name, its values, its child records."""

    name: str
    values: list = field(default_factory=list)
    children: list[Node] = field(default_factory=list)

    def add(self, name: str, *values, children: list[Node] | None = None) -> Node:
        """Append a child record and return it."""
        child = Node(name, list(values), children or [])
        self.children.append(child)
        return child


def encode_value(value) -> bytes:
    """One value's type code and bytes (module doc)."""
    if isinstance(value, (bool, np.bool_)):
        return b"C" + (b"\x01" if value else b"\x00")
    if isinstance(value, Long):
        return b"L" + struct.pack("<q", value)
    if isinstance(value, (int, np.integer)):
        return b"I" + struct.pack("<i", int(value))
    if isinstance(value, np.float32):
        return b"F" + struct.pack("<f", value)
    if isinstance(value, float):
        return b"D" + struct.pack("<d", value)
    if isinstance(value, str):
        data = value.encode("utf-8")
        return b"S" + struct.pack("<I", len(data)) + data
    if isinstance(value, bytes):
        return b"R" + struct.pack("<I", len(value)) + value
    if isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value.reshape(-1))
        code = ARRAY_CODES.get(array.dtype)
        if code is None:
            raise TypeError(f"no FBX array type for dtype {array.dtype}")
        data = array.astype(array.dtype.newbyteorder("<"), copy=False).tobytes()
        encoding = 0
        if len(data) > COMPRESS_BYTES:
            packed = zlib.compress(data, 6)
            if len(packed) < len(data):
                data, encoding = packed, 1
        return code + struct.pack("<III", len(array), encoding, len(data)) + data
    raise TypeError(f"no FBX value type for {type(value).__name__}")


def _encode_node(node: Node, start: int, wide: bool) -> bytes:
    """The record's bytes when it begins at absolute offset `start`."""
    name = node.name.encode("ascii")
    values = b"".join(encode_value(v) for v in node.values)
    head_size = (24 if wide else 12) + 1 + len(name)
    body = bytearray(values)
    for child in node.children:
        body += _encode_node(child, start + head_size + len(body), wide)
    if node.children or not node.values or node.name in ALWAYS_NULL_RECORD:
        body += null_record(wide)
    end = start + head_size + len(body)
    counts = struct.pack("<QQQ" if wide else "<III", end, len(node.values), len(values))
    return counts + struct.pack("<B", len(name)) + name + bytes(body)


def null_record(wide: bool) -> bytes:
    return b"\x00" * (25 if wide else 13)


def _footer(offset: int, version: int) -> bytes:
    """What follows the top-level null record, `offset` being where the footer starts: the
    footer id, four zero bytes, zeros up to the next multiple of 16 (16 when already there),
    the version again, 120 zero bytes and the closing 16-byte magic."""
    head = FOOTER_ID + b"\x00" * 4
    pad = -(offset + len(head)) % 16 or 16
    return head + b"\x00" * pad + struct.pack("<I", version) + b"\x00" * 120 + FOOTER_MAGIC


def encode(nodes: list[Node], version: int = 7400) -> bytes:
    """The bytes of a binary FBX file whose top level is `nodes`."""
    if version not in VERSIONS:
        raise ValueError(f"FBX version must be one of {VERSIONS}, got {version}")
    wide = version >= 7500
    out = bytearray(MAGIC + struct.pack("<I", version))
    for node in nodes:
        out += _encode_node(node, len(out), wide)
    out += null_record(wide)
    return bytes(out + _footer(len(out), version))


def properties(*entries: tuple) -> Node:
    """A Properties70 record: one P child per (name, type, label, flags, *values) tuple."""
    return Node("Properties70", [], [Node("P", list(entry)) for entry in entries])
