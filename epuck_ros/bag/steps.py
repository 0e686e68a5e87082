"""The step a recorded message names, read from its CDR bytes: what a lockstep run's bag logs it at.

Every message of a simulator step names the step (README, "Same seed, same run"): a header's stamp or a time as its
first field (`odom`, `proximity`, `camera/*`, `/clock`...), the first transform's stamp of a `tf2_msgs/TFMessage`, or
for a `std_msgs/Float64MultiArray` (`ir_raw`, a stamped `wheel_cmd`...) the layout's `stamp=SEC.NANOSEC` label. The
recorder logs such a message at that simulated time, not at the moment it happened to arrive: a lockstep run's bag is
then a function of the run, equal to the headless trial's. No ROS needed.
"""
from __future__ import annotations

import re
import struct
from collections.abc import Callable

from epuck_ros.bag.cdr import CDR_LE, ENCAPSULATION
from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_label
from epuck_ros.swarm_messages import COMMAND_TOPIC as SWARM_COMMAND_TOPIC

StepReader = Callable[[bytes], 'int | None']
"""The step (ns of simulated time) a message's bytes name, None if they name none. A stamp of 0 names none: the
simulator's first step is at one time step, and what it stamps 0 comes before the run (`/tf_static`)."""

_STAMP_TYPES = ('Header', 'std_msgs/Header', 'std_msgs/msg/Header',
                'builtin_interfaces/Time', 'builtin_interfaces/msg/Time')
_FIRST_FIELD = re.compile(r'^\s*([A-Za-z0-9_/]+)\s+\w+\s*(?:#.*)?$', re.MULTILINE)
_TIME = struct.Struct('<iI')
_COUNT = struct.Struct('<I')
_LABEL_MAX = 64
"""Bytes a `stamp=SEC.NANOSEC` label has at most (with its NUL): a longer one names no step."""
_TF_FIRST_STAMP = ENCAPSULATION + 4
"""A TFMessage: the transforms' count, then the first TransformStamped's header stamp."""
ARRAY_TYPE = 'std_msgs/msg/Float64MultiArray'
TF_TYPE = 'tf2_msgs/msg/TFMessage'


def first_field_is_stamp(schema_text: str) -> bool:
    """Whether a ros2msg schema's first field is a header or a time (its stamp right after the encapsulation)."""
    match = _FIRST_FIELD.search(schema_text.split('\n===', 1)[0])
    return match is not None and match.group(1) in _STAMP_TYPES


def _stamp_at(offset: int) -> StepReader:
    def read(data: bytes) -> int | None:
        if len(data) < offset + _TIME.size or data[1] != CDR_LE:
            return None
        sec, nanosec = _TIME.unpack_from(data, offset)
        return nanoseconds_from_stamp(sec, nanosec) if sec >= 0 and nanosec < 1_000_000_000 and (sec or nanosec) \
            else None
    return read


def _first_transform(data: bytes) -> int | None:
    if len(data) < _TF_FIRST_STAMP or data[1] != CDR_LE or not struct.unpack_from('<I', data, ENCAPSULATION)[0]:
        return None
    return _stamp_at(_TF_FIRST_STAMP)(data)


def _labelled_array(data: bytes) -> int | None:
    """A little-endian Float64MultiArray's step: its first dimension's label (uint32 length with its NUL, then the
    bytes) is a stamp label (a robot's array has that one dimension; a swarm's has its robots and fields after it)."""
    if len(data) < ENCAPSULATION + 8 or data[1] != CDR_LE or _COUNT.unpack_from(data, ENCAPSULATION)[0] < 1:
        return None
    length = _COUNT.unpack_from(data, ENCAPSULATION + 4)[0]
    start = ENCAPSULATION + 8
    if not 0 < length <= _LABEL_MAX or len(data) < start + length:
        return None
    stamp = stamp_from_label(data[start:start + length - 1].decode('ascii', errors='replace'))
    return None if stamp is None or stamp == (0, 0) else nanoseconds_from_stamp(*stamp)


ANSWER_TOPICS = ('wheel_cmd', 'cmd_vel')
"""The topics (last name) a robot's lockstep controller answers each step on, naming it."""


def is_answer_topic(topic: str) -> bool:
    """Whether a topic carries controllers' answers (a robot's or a swarm's)."""
    return topic.rsplit('/', 1)[-1] in ANSWER_TOPICS or topic.endswith('/' + SWARM_COMMAND_TOPIC)


def step_reader(type_name: str, schema_text: str) -> StepReader | None:
    """How to read the step a message of this type names; None for a type that names none (a String, a count)."""
    if type_name == ARRAY_TYPE:
        return _labelled_array
    if type_name == TF_TYPE:
        return _first_transform
    return _stamp_at(ENCAPSULATION) if first_field_is_stamp(schema_text) else None


SENSES_ON_TOPIC = 'senses_on'
"""Each robot's latched topic (std_msgs/String) of which sense topics the simulator publishes since which step: a
sense is computed only while something asks for it, so a bag's sense topic has no messages for the steps it was off,
which are not lost (`senses_on_text`)."""
_SENSES_ON = re.compile(r'^from the step after (\d{1,10})\.(\d{9}): (.*)$')


def senses_on_text(after: tuple[int, int], topics: list[str]) -> str:
    """`from the step after 1.024000000: camera/image_raw, camera/camera_info` (topics relative to the robot's, none:
    `none`): from the step after `after` on, exactly these sense topics are published, one message each per step.
    A topic just turned on also has the message of step `after` itself (published at once for a new reader)."""
    return f'from the step after {after[0]}.{after[1]:09d}: ' + (', '.join(topics) or 'none')


def senses_on_from_text(text: str) -> tuple[int, list[str]] | None:
    """(after, in ns; topics) of a `senses_on_text`, None for any other text."""
    match = _SENSES_ON.match(text)
    if match is None:
        return None
    listed = match[3].strip()
    return nanoseconds_from_stamp(int(match[1]), int(match[2])), [] if listed == 'none' else listed.split(', ')
