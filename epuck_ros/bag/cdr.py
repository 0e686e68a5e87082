"""Decoding CDR message data without ROS: a generic decoder driven by the bag's ``ros2msg`` schema,
and fast paths for the two types a run summary reads a lot of (Odometry and Range).

The fast paths read a few fields with ``struct`` at offsets computed from the layout: CDR
aligns each primitive to its size, counted from after the 4-byte encapsulation header, and
the only variable-length parts before the numbers are the frame_id strings.

Message data is untrusted: every read is checked against the message's end, sequence counts are
bounded by the bytes left (every element takes at least one byte: an empty struct is serialised
as one uint8, as rosidl does) and in total per message, and type nesting is bounded, so a corrupt or hostile bag gives a
`CdrError` rather than a traceback, gigabytes of memory, or figures read from the next message.
"""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass

from epuck_ros.conversions import NS_PER_SECOND, nanoseconds_from_stamp, yaw_from_quaternion

ENCAPSULATION = 4
"""Bytes of the CDR encapsulation header in front of every message."""
CDR_LE, CDR_BE = 1, 0

_PRIMITIVES = {
    'bool': '?', 'byte': 'B', 'char': 'B', 'int8': 'b', 'uint8': 'B', 'int16': 'h', 'uint16': 'H',
    'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q', 'float32': 'f', 'float64': 'd',
}
_SIZES = {name: struct.calcsize(code) for name, code in _PRIMITIVES.items()}
_TIME_TYPES = ('builtin_interfaces/Time', 'builtin_interfaces/Duration')
_BUILTIN_DEFINITIONS = {name: [('int32', 'sec', None), ('uint32', 'nanosec', None)] for name in _TIME_TYPES}
_FIELD_TYPE = re.compile(r'^([A-Za-z0-9_/]+)(?:<=\d+)?(?:\[(<=)?(\d*)\])?$')
_SEPARATOR = re.compile(r'^={3,}$', re.MULTILINE)
MAX_DEPTH = 64
"""Deepest nesting of message types accepted (ROS messages nest a handful of levels)."""
MAX_ELEMENTS = 4_000_000
"""Most array elements decoded from one message (a 640x480 RGB image has 921,600): each becomes a Python
object, and a few KB of zstd can inflate to a chunk of hundreds of MB of zeros."""
_EMPTY_STRUCT = [('uint8', 'structure_needs_at_least_one_member', None)]
"""What rosidl puts in an empty message, so that it serialises as one byte."""


class CdrError(ValueError):
    """Message data or schema the decoder cannot handle; the message says what."""


_HEADER = struct.Struct('<iII')  # stamp sec, nanosec, frame_id length
_LENGTH = struct.Struct('<I')
_POSE = struct.Struct('<7d')  # position x y z, orientation x y z w
_TWIST = struct.Struct('<6d')
_FLOAT = struct.Struct('<f')
_POSE_AND_COVARIANCE = 7 * 8 + 36 * 8


def _little_endian_base(buffer: bytes, start: int, end: int) -> int:
    """Where the CDR data starts (after the encapsulation header); only little-endian is read here."""
    if end - start < ENCAPSULATION + _HEADER.size:
        raise CdrError(f'message of {end - start} bytes is too short for a header')
    if buffer[start + 1] != CDR_LE:
        raise CdrError(f'encapsulation {bytes(buffer[start:start + 2]).hex()} is not little-endian CDR')
    return start + ENCAPSULATION


def _cut_short(type_name: str) -> CdrError:
    return CdrError(f'{type_name}: message data ends before the message does')


def odometry_fields(buffer: bytes, start: int, end: int | None = None) -> tuple[int, float, float, float, float, float]:
    """nav_msgs/Odometry -> (header stamp ns, x, y, yaw, linear.x, angular.z); data ends at `end`."""
    end = len(buffer) if end is None else min(end, len(buffer))
    base = _little_endian_base(buffer, start, end)
    sec, nanosec, frame_length = _HEADER.unpack_from(buffer, base)
    child = base + ((12 + frame_length + 3) & -4)
    if child + 4 > end:
        raise _cut_short('nav_msgs/Odometry')
    (child_length,) = _LENGTH.unpack_from(buffer, child)
    pose = base + ((child - base + 4 + child_length + 7) & -8)
    if pose + _POSE_AND_COVARIANCE + _TWIST.size > end:
        raise _cut_short('nav_msgs/Odometry')
    x, y, _, qx, qy, qz, qw = _POSE.unpack_from(buffer, pose)
    vx, _, _, _, _, wz = _TWIST.unpack_from(buffer, pose + _POSE_AND_COVARIANCE)
    return nanoseconds_from_stamp(sec, nanosec), x, y, yaw_from_quaternion(qx, qy, qz, qw), vx, wz


def range_fields(buffer: bytes, start: int, end: int | None = None) -> tuple[int, float, bytes]:
    """sensor_msgs/Range -> (header stamp ns, range, frame_id as UTF-8 bytes); data ends at `end`."""
    end = len(buffer) if end is None else min(end, len(buffer))
    base = _little_endian_base(buffer, start, end)
    sec, nanosec, frame_length = _HEADER.unpack_from(buffer, base)
    # after frame_id: radiation_type (uint8), then 4-aligned field_of_view, min_range, max_range, range
    distance_at = base + ((12 + frame_length + 4) & -4) + 12
    if distance_at + 4 > end:
        raise _cut_short('sensor_msgs/Range')
    (distance,) = _FLOAT.unpack_from(buffer, distance_at)
    return nanoseconds_from_stamp(sec, nanosec), distance, bytes(buffer[base + 12:base + 11 + frame_length])


def shortest_float32(value: float) -> float:
    """The shortest decimal that reads back as the same float32: 0.05, not 0.05000000074505806."""
    for digits in range(6, 10):
        short = float(f'{value:.{digits}g}')
        if struct.unpack('<f', struct.pack('<f', short))[0] == value:
            return short
    return value


@dataclass(frozen=True)
class TimeValue:
    """A builtin_interfaces Time or Duration, kept exact in nanoseconds."""

    nanoseconds: int

    def __str__(self) -> str:
        sign = '-' if self.nanoseconds < 0 else ''
        seconds, nanoseconds = divmod(abs(self.nanoseconds), NS_PER_SECOND)
        return f'{sign}{seconds}.{nanoseconds:09d}'


def _aligned(position: int, base: int, size: int) -> int:
    """The next offset at a multiple of `size` counted from `base` (CDR alignment)."""
    return base + ((position - base + size - 1) & -size)


def _short_name(type_name: str) -> str:
    """``pkg/msg/Type`` and ``pkg/Type`` -> ``pkg/Type``, the key the schema's MSG: blocks use."""
    parts = type_name.split('/')
    return f'{parts[0]}/{parts[-1]}' if len(parts) > 1 else type_name


def parse_schema(type_name: str, text: str) -> dict[str, list[tuple[str, str, int | None]]]:
    """ros2msg text -> {``pkg/Type``: [(field type, field name, array length or -1 for a sequence)]}."""
    definitions = dict(_BUILTIN_DEFINITIONS)
    name = _short_name(type_name)
    for block in _SEPARATOR.split(text):
        lines = block.strip('\n').split('\n')
        if lines and lines[0].startswith('MSG: '):
            name = _short_name(lines.pop(0)[5:].strip())
        package = name.split('/')[0]
        fields = []
        for line in lines:
            words = line.split('#', 1)[0].split()
            if len(words) < 2 or '=' in words[1] or (len(words) > 2 and words[2].startswith('=')):
                continue  # blank, comment or constant
            match = _FIELD_TYPE.match(words[0])
            if match is None:
                raise CdrError(f'{type_name}: cannot parse field type {words[0]!r}')
            base_type, bounded, length = match.groups()
            if base_type not in _PRIMITIVES and base_type not in ('string', 'wstring'):
                base_type = _short_name(base_type if '/' in base_type else f'{package}/{base_type}')
            if length and len(length) > 10:
                raise CdrError(f'{type_name}: array length {length[:20]}... is not a size')
            array = None if '[' not in words[0] else (-1 if bounded or not length else int(length))
            fields.append((base_type, words[1], array))
        definitions[name] = fields or _EMPTY_STRUCT
    return definitions


class CdrDecoder:
    """Decodes one message type, from its bag schema, into nested dicts; `flat` gives dotted columns.

    float32 values come out as their shortest decimal (`shortest_float32`), as ROS tools print them.
    """

    def __init__(self, type_name: str, schema_text: str) -> None:
        self.type_name = _short_name(type_name)
        self._definitions = parse_schema(type_name, schema_text)
        self._check(self.type_name, ())

    def _check(self, name: str, path: tuple[str, ...]) -> None:
        if name not in self._definitions:
            raise CdrError(f'{self.type_name}: the schema has no definition for {name}')
        if name in path:
            raise CdrError(f'{self.type_name}: {name} contains itself')
        if len(path) >= MAX_DEPTH:
            raise CdrError(f'{self.type_name}: types nested more than {MAX_DEPTH} levels deep')
        for field_type, field_name, _ in self._definitions[name]:
            if field_type == 'wstring':
                raise CdrError(f'{self.type_name}: field {field_name} is a wstring, which is not supported')
            if field_type not in _PRIMITIVES and field_type != 'string':
                self._check(field_type, (*path, name))

    def decode(self, buffer: bytes, start: int = 0, end: int | None = None) -> dict:
        return self._decode(buffer, start, end)[0]

    def size(self, buffer: bytes, start: int = 0) -> int:
        """Bytes the message really takes, encapsulation header included (buffers may carry more)."""
        return self._decode(buffer, start, None)[1] - start

    def _decode(self, buffer: bytes, start: int, end: int | None) -> tuple[dict, int]:
        end = len(buffer) if end is None else min(end, len(buffer))
        if end - start < ENCAPSULATION:
            raise CdrError(f'{self.type_name}: message of {max(end - start, 0)} bytes has no CDR header')
        kind = buffer[start + 1]
        if kind not in (CDR_LE, CDR_BE) or buffer[start] != 0:
            raise CdrError(f'encapsulation {bytes(buffer[start:start + 2]).hex()} is not plain CDR')
        self._order = '<' if kind == CDR_LE else '>'
        self._base = start + ENCAPSULATION
        self._end = end
        self._elements_left = MAX_ELEMENTS
        try:
            value, position = self._read_message(buffer, self.type_name, self._base)
        except struct.error:
            position = end + 1
        if position > end:
            raise _cut_short(self.type_name)
        return value, position

    def _read_message(self, buffer: bytes, name: str, position: int) -> tuple[object, int]:
        message = {}
        for field_type, field_name, array in self._definitions[name]:
            if array is None:
                message[field_name], position = self._read_value(buffer, field_type, position)
                continue
            if array < 0:
                position = _aligned(position, self._base, 4)
                (array,) = struct.unpack_from(self._order + 'I', buffer, position)
                position += 4
            if array > self._end - position:  # each element takes at least one byte
                raise _cut_short(self.type_name)
            self._elements_left -= array
            if self._elements_left < 0:
                raise CdrError(f'{self.type_name}: more than {MAX_ELEMENTS:,} array elements in one message')
            message[field_name], position = self._read_array(buffer, field_type, array, position)
        if name in _TIME_TYPES:
            return TimeValue(nanoseconds_from_stamp(message['sec'], message['nanosec'])), position
        return message, position

    def _read_array(self, buffer: bytes, field_type: str, count: int, position: int) -> tuple[list, int]:
        code = _PRIMITIVES.get(field_type)
        if code is None:
            values = []
            for _ in range(count):
                value, position = self._read_value(buffer, field_type, position)
                values.append(value)
            return values, position
        size = _SIZES[field_type]
        position = _aligned(position, self._base, size) if count else position
        values = list(struct.unpack_from(f'{self._order}{count}{code}', buffer, position))
        if field_type == 'float32':
            values = [shortest_float32(v) for v in values]
        return values, position + size * count

    def _read_value(self, buffer: bytes, field_type: str, position: int) -> tuple[object, int]:
        code = _PRIMITIVES.get(field_type)
        if code is not None:
            size = _SIZES[field_type]
            position = _aligned(position, self._base, size)
            (value,) = struct.unpack_from(self._order + code, buffer, position)
            return shortest_float32(value) if field_type == 'float32' else value, position + size
        if field_type == 'string':
            position = _aligned(position, self._base, 4)
            (length,) = struct.unpack_from(self._order + 'I', buffer, position)
            if length > self._end - position - 4:
                raise _cut_short(self.type_name)
            text = bytes(buffer[position + 4:position + 4 + max(length - 1, 0)]).decode('utf-8', 'replace')
            return text, position + 4 + length
        return self._read_message(buffer, field_type, position)

    def flat(self, buffer: bytes, start: int = 0, end: int | None = None,
             join_arrays: bool = False) -> dict[str, object]:
        """One message as {dotted.name or name[i]: value}; primitive arrays joined by spaces if asked."""
        columns: dict[str, object] = {}
        _flatten(self.decode(buffer, start, end), '', columns, join_arrays)
        return columns


def _flatten(value: object, name: str, columns: dict[str, object], join_arrays: bool) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(item, f'{name}.{key}' if name else key, columns, join_arrays)
    elif isinstance(value, list):
        if join_arrays and not any(isinstance(v, (dict, list)) for v in value):
            columns[name] = ' '.join(str(v) for v in value)
            return
        for index, item in enumerate(value):
            _flatten(item, f'{name}[{index}]', columns, join_arrays)
    else:
        columns[name] = value
