"""How ROS messages carry time and heading, converted in one place: stamps <-> seconds, yaw <-> quaternion.

A stamp is (sec, nanosec) as builtin_interfaces/Time holds it; nanoseconds since the epoch (or since the
simulation's start) are the exact form used to compare stamps. A message without a header (the Float64MultiArray
of `ir_raw`, `ground_raw`, `light_raw` and a stamped `wheel_cmd`) names its step in its layout: one dimension
describing the data, labelled `stamp=SEC.NANOSEC` (`stamp_label`), which readers of `data` never see. A planar
pose's orientation is a rotation about z, so its quaternion is (0, 0, sin(yaw / 2), cos(yaw / 2)). No ROS imports:
the core, the bag code and the nodes all use these.
"""
from __future__ import annotations

import math

NS_PER_SECOND = 1_000_000_000


def nanoseconds_from_seconds(seconds: float) -> int:
    """A time in seconds as integer nanoseconds, to the nearest one (a step's stamp as one integer)."""
    return round(seconds * 1e9)


def stamp_from_seconds(seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds, to the nearest nanosecond."""
    return divmod(nanoseconds_from_seconds(seconds), NS_PER_SECOND)


def stamp_from_nanoseconds(nanoseconds: int) -> tuple[int, int]:
    """(sec, nanosec) of a time in whole nanoseconds."""
    return divmod(nanoseconds, NS_PER_SECOND)


def nanoseconds_from_stamp(sec: int, nanosec: int) -> int:
    """A stamp as whole nanoseconds: exact, so two stamps compare equal when they are."""
    return sec * NS_PER_SECOND + nanosec


STAMP_LABEL_PREFIX = 'stamp='
MAX_STAMP_SEC = 2**31 - 1
"""builtin_interfaces/Time's `sec` is an int32: no step is later, so no label may name a later one."""


def stamp_label(sec: int, nanosec: int) -> str:
    """The label that names a step in a Float64MultiArray's layout: `stamp=12.032000000` (nanosec in 9 digits)."""
    return f'{STAMP_LABEL_PREFIX}{sec}.{nanosec:09d}'


def stamp_from_label(label: str) -> tuple[int, int] | None:
    """The (sec, nanosec) a `stamp_label` names; None for any other label (an array that names no step).

    Only ASCII digits, at most 10 for `sec` and within an int32: `str.isdigit()` alone accepts Unicode digits
    (`²`, which `int()` refuses, or `٣`, which it reads as 3), and an unbounded `sec` named a step beyond any float.
    """
    if not label.startswith(STAMP_LABEL_PREFIX):
        return None
    sec, dot, nanosec = label[len(STAMP_LABEL_PREFIX):].partition('.')
    if not dot or len(nanosec) != 9 or not 1 <= len(sec) <= 10:
        return None
    if not _ascii_digits(sec) or not _ascii_digits(nanosec):
        return None
    return (int(sec), int(nanosec)) if int(sec) <= MAX_STAMP_SEC else None


def _ascii_digits(text: str) -> bool:
    return text.isascii() and text.isdigit()


def seconds_from_stamp(sec: int, nanosec: int) -> float:
    """A stamp in seconds (a float: for display and rates, not for comparing stamps)."""
    return sec + nanosec * 1e-9


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """The heading (rad) of an orientation quaternion, its rotation about z."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw: float) -> tuple[float, float]:
    """(z, w) of the quaternion of a rotation by `yaw` about z (x and y are 0)."""
    return math.sin(yaw / 2.0), math.cos(yaw / 2.0)
