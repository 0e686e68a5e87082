"""Step messages published as CDR bytes: serialised once by rclpy, then only their changing numbers patched.

Why hand-written: `Publisher.publish(msg)` converts the Python message to C and serialises it on every call;
for an Odometry (two 36-double covariances) that costs several times what publishing the bytes does
(bench_sim_node in the README).
The simulator sends 13 messages per robot and step, so this is most of its cost. A `Patch` is built from a
real message, serialised exactly (`exact_cdr`), and the offset of each field that changes is found by setting it
to a marker value and locating the marker's bytes. Each step the numbers are packed into a copy of those bytes,
which any subscriber reads as a normal message.

Why not rclpy's `serialize_message` for the template: it returns the serializer's buffer, which is longer than the
CDR (a JointState of 120 bytes came as 124 or 132) and whose alignment padding is uninitialised memory; rosbags
refuses such a message ("CDR message size mismatch") and every copy would carry the stale bytes. rosbags' typestore
writes the exact CDR with zero padding, as Fast DDS does for `publish(msg)` on the wire.

A Float64MultiArray that names its step (`ir_raw`, `ground_raw`, `light_raw`, a stamped `wheel_cmd`: one
dimension labelled `conversions.stamp_label`) is written whole by `array_bytes`: its label's length changes with the
time, so it cannot be a Patch; packing it is a few struct calls (test_serialized checks it against rosbags' bytes).

The other way round, `array_values` reads the numbers of a Float64MultiArray received as bytes (`raw=True`) and
the step its label names: rclpy would build a message object, its layout and an array for them, many times the
cost of reading the numbers, on both sides of every lockstep round trip (`ir_raw`, `wheel_cmd`).
"""
from __future__ import annotations

import struct
from collections.abc import Hashable, Sequence
from functools import cache
from typing import Any

import numpy as np
from rosbags.serde import SerdeError

from epuck_ros.conversions import stamp_from_label, stamp_label

_LITTLE_ENDIAN_CDR = b'\x00\x01'
_ARRAY_HEAD = struct.Struct('<2xHIII')
"""Float64MultiArray's CDR up to its numbers: encapsulation (2 bytes kind, 2 options), layout.dim count,
layout.data_offset, data count; with no dims the float64s follow at byte 20 (8-aligned after the header)."""
_ARRAY_DATA = 20
_ENCAPSULATION = _LITTLE_ENDIAN_CDR + b'\x00\x00'
_NO_DIMS = struct.Struct('<III')
"""A Float64MultiArray without dimensions after its encapsulation: dim count (0), data_offset, data count."""
_ONE_DIM = struct.Struct('<4sII')
"""The start of a Float64MultiArray with one dimension: encapsulation, dim count (1), its label's length (with NUL)."""
_AFTER_LABEL = struct.Struct('<IIII')
"""After the label, 4-aligned: the dimension's size and stride, layout.data_offset, the data count."""
_HEADER = 4
"""CDR aligns relative to the end of the 4-byte encapsulation header."""
_MARKERS = {'d': 1.234567890123e-271, 'f': 1.2345678e-31, 'i': 0x5A3C1E2F, 'I': 0x6B4D2F31}
"""Values no field of our messages holds, whose bytes cannot occur by chance (a different one for each field)."""


class Patch:
    """`msg` serialised once; `fields` are attribute paths with a struct code, e.g. ('header.stamp.sec', 'i'),
    ('position[1]', 'd') or ('transforms[1].header.stamp.sec', 'i'). `bytes(values)` returns the message with
    those fields set, in the order given."""

    def __init__(self, msg: Any, fields: Sequence[tuple[str, str]]) -> None:
        offsets = []
        self._paths = [path for path, _ in fields]
        self._markers = [_MARKERS[code] * (index + 1) if code in 'df' else _MARKERS[code] + index
                         for index, (_, code) in enumerate(fields)]
        for (path, code), marker in zip(fields, self._markers):
            saved = _get(msg, path)
            _set(msg, path, marker)
            data = exact_cdr(msg)
            _set(msg, path, saved)
            packed = struct.pack('<' + code, marker)
            found = data.find(packed)
            if found < 0 or data.find(packed, found + 1) >= 0 or data[:2] != _LITTLE_ENDIAN_CDR:
                raise ValueError(f'cannot locate {path} in the serialised {type(msg).__name__}')
            offsets.append(found)
        self._template = exact_cdr(msg)
        self._struct = struct.Struct('<' + ''.join(code for _, code in fields))
        # one pack of all values, then each value's bytes copied to its offset
        self._slices = []
        position = 0
        for offset, (_, code) in zip(offsets, fields):
            size = struct.calcsize('<' + code)
            self._slices.append((offset, offset + size, position, position + size))
            position += size

    def like(self, msg: Any) -> Patch:
        """The same fields in `msg`, a message of the same type with the same layout: another robot's, its frame ids
        as long. One serialisation instead of one per field; ValueError if its fields lie elsewhere.

        `msg` is serialised with the markers in its fields: its bytes are the patch's if each field's marker lies at
        the field's offset (the marked bytes are then the new template with the markers patched in), and the new
        template is those bytes with the message's own values patched back."""
        saved = [_get(msg, path) for path in self._paths]
        for path, marker in zip(self._paths, self._markers):
            _set(msg, path, marker)
        try:
            marked = exact_cdr(msg)
        finally:
            for path, value in zip(self._paths, saved):
                _set(msg, path, value)
        patch = object.__new__(Patch)
        patch._paths, patch._markers, patch._struct, patch._slices = self._paths, self._markers, self._struct, \
            self._slices
        patch._template = marked
        if len(marked) != len(self._template) or patch.bytes(self._markers) != marked:
            raise ValueError(f'{type(msg).__name__} is not laid out as the patch\'s message')
        patch._template = patch.bytes(saved)
        return patch

    def bytes(self, values: Sequence[float | int]) -> bytes:
        packed = self._struct.pack(*values)
        buffer = bytearray(self._template)
        for start, end, first, last in self._slices:
            buffer[start:end] = packed[first:last]
        return bytes(buffer)


class PatchCache:
    """Patches of many messages of a few layouts (a swarm's robots send the same messages, their frame ids as long
    for names as long): the first message of each layout is located field by field (`Patch`), the others from it
    (`Patch.like`), one serialisation each instead of one per field."""

    def __init__(self) -> None:
        self._first: dict[Hashable, Patch] = {}

    def patch(self, msg: Any, fields: Sequence[tuple[str, str]], layout: Hashable) -> Patch:
        """`Patch(msg, fields)`; `layout` tells messages of one type laid out alike (the length of their frame ids).
        A wrong `layout` costs time, never a wrong patch: `like` checks, and a message it refuses gets its own."""
        key = (type(msg), tuple(fields), layout)
        first = self._first.get(key)
        if first is None:
            first = self._first[key] = Patch(msg, fields)
            return first
        try:
            return first.like(msg)
        except ValueError:
            return Patch(msg, fields)


@cache
def _typestore() -> Any:
    """The Jazzy typestore of rosbags, made on first use: it cost every node process 60 ms at import (rosbags builds
    every distribution's store before Jazzy's), and most never need it."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


_FLOAT64_ARRAY = 'std_msgs/msg/Float64MultiArray'
_DTYPES = {'double': np.float64, 'float': np.float32, 'int8': np.int8, 'uint8': np.uint8, 'octet': np.uint8,
           'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32, 'uint32': np.uint32, 'int64': np.int64,
           'uint64': np.uint64, 'boolean': np.bool_, 'char': np.uint8}
"""rosidl's primitive names -> the NumPy types rosbags keeps arrays of primitives in."""


def exact_cdr(msg: Any) -> bytes:
    """`msg` (an rclpy message) as the exact little-endian CDR of its type: its own length, zero padding."""
    return bytes(_typestore().serialize_cdr(_as_rosbags(msg), _type_name(msg)))


def _type_name(msg: Any) -> str:
    return f'{type(msg).__module__.split(".")[0]}/msg/{type(msg).__name__}'


def _as_rosbags(msg: Any) -> Any:
    """The rosbags message holding the same values as the rclpy message `msg`."""
    values = {}
    for name, kind in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        element = kind.split('<')[-1].split('[')[0].rstrip('>').split(',')[0]
        if hasattr(value, 'get_fields_and_field_types'):
            values[name] = _as_rosbags(value)
        elif '[' in kind or kind.startswith('sequence<'):
            if element in _DTYPES:
                values[name] = np.array(value, dtype=_DTYPES[element])
            else:
                values[name] = [_as_rosbags(item) if hasattr(item, 'get_fields_and_field_types') else item
                                for item in value]
        else:   # rclpy holds an octet (DiagnosticStatus.level) as one byte, rosbags as its number
            values[name] = value[0] if kind == 'octet' else value
    return _typestore().types[_type_name(msg)](**values)


def _get(msg: Any, path: str) -> Any:
    parent, name, index = _resolve(msg, path)
    value = getattr(parent, name)
    return value if index is None else value[index]


def _set(msg: Any, path: str, value: Any) -> None:
    parent, name, index = _resolve(msg, path)
    if index is None:
        setattr(parent, name, value)
    else:
        getattr(parent, name)[index] = value


def _resolve(msg: Any, path: str) -> tuple[Any, str, int | None]:
    *parents, last = path.split('.')
    for part in parents:   # 'transforms[1]' steps into an element
        name, bracket, rest = part.partition('[')
        msg = getattr(msg, name)
        msg = msg[int(rest.rstrip(']'))] if bracket else msg
    name, bracket, rest = last.partition('[')
    return msg, name, int(rest.rstrip(']')) if bracket else None


def array_bytes(values: Sequence[float], stamp: tuple[int, int] | None = None) -> bytes:
    """A std_msgs/Float64MultiArray of `values` as its exact little-endian CDR; with `stamp` (sec, nanosec), named by
    that step: one dimension (size and stride the count) labelled `stamp_label(*stamp)`, data_offset 0."""
    count = len(values)
    numbers = struct.pack(f'<{count}d', *values)
    if stamp is None:
        return b''.join((_ENCAPSULATION, _NO_DIMS.pack(0, 0, count), bytes(4 if count else 0), numbers))
    label = stamp_label(*stamp).encode() + b'\x00'
    end = _ONE_DIM.size + len(label)
    middle = _AFTER_LABEL.pack(count, count, 0, count)
    pad_label = -(end - _HEADER) % 4
    end += pad_label + _AFTER_LABEL.size
    pad_data = -(end - _HEADER) % 8 if count else 0
    return b''.join((_ONE_DIM.pack(_ENCAPSULATION, 1, len(label)), label, bytes(pad_label), middle, bytes(pad_data),
                     numbers))


def array_values(data: bytes) -> tuple[tuple[float, ...], tuple[int, int] | None] | None:
    """The numbers of a serialised std_msgs/Float64MultiArray and the step its label names (None: it names none),
    or None if the bytes are not one (a publisher may send any bytes). Our own two layouts (none, and one labelled
    dimension) are read here; any other, or big-endian, by rosbags, never by rclpy: rclpy's C deserialiser prints a
    line to stderr for each bad message, which a publisher of bad bytes would turn into a flood (the caller's
    throttled warning is all they should cost). rosbags reads XCDR1, the encoding ROS 2 Jazzy's middlewares send
    for this type; XCDR2 is refused like any other bytes that are no Float64MultiArray."""
    if data[:2] == _LITTLE_ENDIAN_CDR and len(data) >= _ARRAY_DATA:
        _, dims, _, count = _ARRAY_HEAD.unpack_from(data)
        if dims == 0 and len(data) >= _ARRAY_DATA + 8 * count:
            return struct.unpack_from(f'<{count}d', data, _ARRAY_DATA), None
        if dims == 1:
            read = _one_labelled_dimension(data)
            if read is not None:
                return read
    try:
        msg = _typestore().deserialize_cdr(data, _FLOAT64_ARRAY)
    except SerdeError:
        return None
    dims = msg.layout.dim
    return tuple(float(value) for value in msg.data), stamp_from_label(dims[0].label) if len(dims) == 1 else None


def _one_labelled_dimension(data: bytes) -> tuple[tuple[float, ...], tuple[int, int] | None] | None:
    """`array_values` of the layout `array_bytes` writes with a stamp; None for anything else (rosbags reads it)."""
    _, _, length = _ONE_DIM.unpack_from(data)
    end = _ONE_DIM.size + length
    if length == 0 or end > len(data) or data[end - 1] != 0:
        return None
    label = data[_ONE_DIM.size:end - 1]
    end += -(end - _HEADER) % 4
    if end + _AFTER_LABEL.size > len(data):
        return None
    _, _, offset, count = _AFTER_LABEL.unpack_from(data, end)
    end += _AFTER_LABEL.size
    end += -(end - _HEADER) % 8 if count else 0
    if offset != 0 or end + 8 * count > len(data):
        return None
    return struct.unpack_from(f'<{count}d', data, end), stamp_from_label(label.decode(errors='replace'))
