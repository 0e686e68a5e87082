"""One message per step for many robots: the swarm observation and the swarm command, as CDR bytes (no rclpy).

Why: a process that drives many robots (`avoid --robots all`) paid, per robot and step, an `ir_raw` and an answer
over DDS, each a synchronous send of tens of microseconds in both processes, plus a `/clock` reader per node: with
50 robots py-spy found both processes spending much of their time in `Publisher.publish` (its figures: the
benchmarks page).
One message per step in each direction carries the same numbers.

The type is std_msgs/Float64MultiArray, as `ir_raw` and `wheel_cmd` (so `ros2 topic echo`, bags, the bag reader and
Foxglove read it, and a step is named the way every array of this package names it): a matrix of one row per robot,
its layout's dimensions
- `stamp=SEC.NANOSEC` (size 1): the step, as `conversions.stamp_label` names it; absent from a message that
  answers no step;
- `robots=epuck0,epuck1,...` (size N): the rows' robots (ROS name tokens: no comma can occur in one);
- `fields=odom_x,odom_y,...` (size K): the columns.
`data` is the N x K numbers row by row, `data_offset` 0. A JointState (header stamp, a name per robot) was the other
candidate; it has three numbers per name, and a robot's step has twenty (odometry, truth, wheels, the eight IR
values), so the names would have been per number (a robot-and-field string for each), many times the bytes and a
string to parse per number. Here the names are one label, read once per layout (`SwarmReader` keeps the last).

A command message whose `fields` are none (`fields=`, no data) is a controller's declaration: it drives these
robots and answers each of their steps by name (`SwarmPorts`: lockstep membership without a wall-clock wait).
"""
from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from epuck_ros.conversions import stamp_from_label, stamp_label
from epuck_ros.model import SENSOR_NAMES
from epuck_ros.simulation import Simulation

OBSERVATION_TOPIC = 'swarm/observation'
COMMAND_TOPIC = 'swarm/command'
ROBOTS_PREFIX = 'robots='
FIELDS_PREFIX = 'fields='
OBSERVATION_FIELDS = ('odom_x', 'odom_y', 'odom_yaw', 'odom_v', 'odom_w', 'truth_x', 'truth_y', 'truth_yaw',
                      'wheel_left', 'wheel_right', 'wheel_left_speed', 'wheel_right_speed',
                      *(f'{sensor}_raw' for sensor in SENSOR_NAMES))
"""Per robot and step: odometry (pose in its odom frame, the yaw in radians; linear and angular speed), ground truth
(pose in the world), the wheel encoders (rad) and applied speeds (rad/s), the eight raw IR values (`ir_raw`)."""
COMMAND_FIELDS = ('left', 'right')
"""Per robot: wheel speeds in rad/s, as `wheel_cmd`."""


def observation_values(sim: Simulation, values: np.ndarray | None = None) -> np.ndarray:
    """Every robot's row of OBSERVATION_FIELDS now (into `values`, robots x fields, when given)."""
    if values is None:
        values = np.empty((len(sim.names), len(OBSERVATION_FIELDS)))
    values[:, 0:3] = sim.odom_pose
    values[:, 3:5] = sim.odom_twist
    values[:, 5:8] = sim.true_pose
    values[:, 8:10] = sim.wheel_angles
    values[:, 10:12] = sim.wheel_speeds
    values[:, 12:20] = sim.ir_raw
    return values


_ENCAPSULATION = b'\x00\x01\x00\x00'
_HEADER = 4
"""CDR aligns relative to the end of the 4-byte encapsulation header."""
_U32 = struct.Struct('<I')
_TWO_U32 = struct.Struct('<II')
MAX_LABEL = 1 << 24
"""Bytes a label may have at most when read (a swarm of 100,000 robots' names fits; a forged length does not)."""


def _aligned(offset: int, to: int) -> int:
    return offset + (-(offset - _HEADER) % to)


def _dimension(label: str, size: int, stride: int, offset: int) -> bytes:
    """One MultiArrayDimension's CDR starting at byte `offset` of the message (4-aligned)."""
    text = label.encode() + b'\x00'
    end = offset + 4 + len(text)
    return b''.join((_U32.pack(len(text)), text, bytes(_aligned(end, 4) - end), _TWO_U32.pack(size, stride)))


class SwarmLayout:
    """A swarm message of fixed robots and fields: its bytes after the stamp are laid out once."""

    def __init__(self, robots: Sequence[str], fields: Sequence[str]) -> None:
        self.robots, self.fields = tuple(robots), tuple(fields)
        self._shape = (len(self.robots), len(self.fields))
        self._robots_label = ROBOTS_PREFIX + ','.join(self.robots)
        self._fields_label = FIELDS_PREFIX + ','.join(self.fields)

    def to_bytes(self, data: np.ndarray, stamp: tuple[int, int] | None) -> bytes:
        """The message: `data` (robots x fields) named by step `stamp` (sec, nanosec); None: it names no step."""
        values = np.ascontiguousarray(data, dtype='<f8')
        if values.shape != self._shape:
            raise ValueError(f'swarm data of shape {self._shape} expected, got {values.shape}')
        rows, columns = self._shape
        parts = [_ENCAPSULATION, _U32.pack(2 if stamp is None else 3)]
        offset = 8
        dims = [] if stamp is None else [(stamp_label(*stamp), 1, rows * columns)]
        dims += [(self._robots_label, rows, rows * columns), (self._fields_label, columns, columns)]
        for label, size, stride in dims:
            part = _dimension(label, size, stride, offset)
            parts.append(part)
            offset += len(part)
        count = rows * columns
        parts.append(_TWO_U32.pack(0, count))   # data_offset, the data's count
        offset += 8
        parts.append(bytes(_aligned(offset, 8) - offset if count else 0))
        parts.append(values.tobytes())
        return b''.join(parts)


@dataclass(frozen=True)
class SwarmArray:
    """A swarm message read: the step it names (None: none), its robots and fields, and its rows."""

    stamp: tuple[int, int] | None
    robots: tuple[str, ...]
    fields: tuple[str, ...]
    data: np.ndarray
    """(robots, fields) float64, read-only (a view of the message's bytes)."""


class SwarmReader:
    """Reads swarm messages received as bytes (`raw=True`); the names of the last layout are kept, so a stream of
    one sender's messages parses its (long) robots label once. Anything that is no swarm message is None: a
    publisher may send any bytes."""

    def __init__(self) -> None:
        self._labels: dict[bytes, tuple[str, ...] | None] = {}

    def read(self, data: bytes) -> SwarmArray | None:
        try:
            return self._read(data)
        except (struct.error, ValueError, UnicodeDecodeError):
            return None

    def _names(self, raw: bytes, prefix: str) -> tuple[str, ...] | None:
        known = self._labels.get(raw, False)
        if known is not False:
            return known
        text = raw.decode()
        names = None
        if text.startswith(prefix):
            body = text[len(prefix):]
            names = tuple(body.split(',')) if body else ()
        if len(self._labels) >= 8:   # a few layouts at a time (the observation, one command per controller)
            self._labels.clear()
        self._labels[raw] = names
        return names

    def _read(self, data: bytes) -> SwarmArray | None:
        if data[:2] != _ENCAPSULATION[:2]:
            return None   # big-endian or XCDR2: not what this package or rclpy on a little-endian host sends
        (dims,) = _U32.unpack_from(data, 4)
        if dims not in (2, 3):
            return None
        offset = 8
        labels, sizes = [], []
        for _ in range(dims):
            (length,) = _U32.unpack_from(data, offset)
            end = offset + 4 + length
            if not 0 < length <= MAX_LABEL or end > len(data) or data[end - 1] != 0:
                return None
            labels.append(bytes(data[offset + 4:end - 1]))
            offset = _aligned(end, 4)
            size, _ = _TWO_U32.unpack_from(data, offset)
            sizes.append(size)
            offset += 8
        stamp = None
        if dims == 3:
            stamp = stamp_from_label(labels[0].decode())
            if stamp is None or sizes[0] != 1:
                return None
        robots, fields = self._names(labels[-2], ROBOTS_PREFIX), self._names(labels[-1], FIELDS_PREFIX)
        if robots is None or fields is None or (len(robots), len(fields)) != tuple(sizes[-2:]):
            return None
        data_offset, count = _TWO_U32.unpack_from(data, offset)
        offset += 8
        if count:
            offset = _aligned(offset, 8)
        if data_offset != 0 or count != len(robots) * len(fields) or offset + 8 * count > len(data):
            return None
        values = np.frombuffer(data, dtype='<f8', count=count, offset=offset).reshape(len(robots), len(fields))
        return SwarmArray(stamp, robots, fields, values)
