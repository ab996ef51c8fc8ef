"""The frame message's schema, read from the shard itself.

Every shard stores the compiled ``FileDescriptorSet`` of ``proto/kitti2pgm/frame.proto`` as the
schema of its frame channel. This module reads the field names and numbers of
``kitti2pgm.Frame`` from that stored schema (the descriptor is itself protobuf, decoded here with a
few lines of wire-format code), so that the package holds no copy of the message definition.
"""

from __future__ import annotations

from typing import Any, Dict, Iterator, Tuple, Union

FRAME_SCHEMA = "kitti2pgm.Frame"
POINTS_SCHEMA = "kitti2pgm.Points"

Buffer = Union[bytes, memoryview]


def varint(buf: Buffer, pos: int) -> Tuple[int, int]:
    """Decodes a base-128 varint at ``pos``; returns (value, next position)."""
    result = shift = 0
    while True:
        b = buf[pos]
        pos += 1
        result |= (b & 0x7F) << shift
        if b < 0x80:
            return result, pos
        shift += 7


def encode_varint(v: int) -> bytes:
    out = bytearray()
    while True:
        b = v & 0x7F
        v >>= 7
        if v:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def fields(buf: Buffer) -> Iterator[Tuple[int, int, Any]]:
    """The (field number, wire type, value) of a message: ints for varints, memoryviews for
    length-delimited fields; fixed-width fields are skipped."""
    buf = memoryview(buf)
    pos, end = 0, len(buf)
    while pos < end:
        key, pos = varint(buf, pos)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, pos = varint(buf, pos)
            yield number, wire, value
        elif wire == 2:
            n, pos = varint(buf, pos)
            chunk = buf[pos:pos + n]
            if len(chunk) != n:
                raise ValueError("truncated protobuf message")
            pos += n
            yield number, wire, chunk
        elif wire == 1:
            pos += 8
        elif wire == 5:
            pos += 4
        else:
            raise ValueError(f"unsupported protobuf wire type {wire}")


# Field numbers of google/protobuf/descriptor.proto (stable since proto2).
_FDS_FILE, _FILE_PACKAGE, _FILE_MESSAGE = 1, 2, 4
_MSG_NAME, _MSG_FIELD = 1, 2
_FIELD_NAME, _FIELD_NUMBER, _FIELD_LABEL, _FIELD_TYPE = 1, 3, 4, 5
# FieldDescriptorProto.Type values used by the frame message.
TYPE_NAMES = {4: "uint64", 9: "string", 12: "bytes", 13: "uint32"}
LABEL_REPEATED = 3


class FrameSchema:
    """Field name -> (number, type name, repeated) of ``kitti2pgm.Frame``, from a stored schema."""

    def __init__(self, descriptor_set: Buffer, message: str = FRAME_SCHEMA):
        package, _, name = message.rpartition(".")
        self.by_name: Dict[str, Tuple[int, str, bool]] = {}
        for n, _w, f in fields(descriptor_set):
            if n != _FDS_FILE:
                continue
            pkg = ""
            messages = []
            for fn, _fw, fv in fields(f):
                if fn == _FILE_PACKAGE:
                    pkg = bytes(fv).decode()
                elif fn == _FILE_MESSAGE:
                    messages.append(fv)
            if pkg != package:
                continue
            for m in messages:
                mname, mfields = "", []
                for mn, _mw, mv in fields(m):
                    if mn == _MSG_NAME:
                        mname = bytes(mv).decode()
                    elif mn == _MSG_FIELD:
                        mfields.append(mv)
                if mname != name:
                    continue
                for fd in mfields:
                    d = {k: v for k, _w2, v in fields(fd)}
                    self.by_name[bytes(d[_FIELD_NAME]).decode()] = (
                        int(d[_FIELD_NUMBER]), TYPE_NAMES.get(int(d.get(_FIELD_TYPE, 0)), "other"),
                        int(d.get(_FIELD_LABEL, 1)) == LABEL_REPEATED)
        if not self.by_name:
            raise ValueError(f"the schema does not define {message}")
        self.by_number = {num: (fname, t, rep) for fname, (num, t, rep) in self.by_name.items()}

    def number(self, name: str) -> int:
        if name not in self.by_name:
            raise ValueError(f"the message has no field {name!r} (a shard of another kitti2pgm version?)")
        return self.by_name[name][0]
