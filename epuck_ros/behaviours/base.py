"""What every behaviour shares: its input, its output, its settings, and the waiting-for-data rule.

A behaviour is a small state machine: each control tick it gets an `Observation` (time, odometry pose,
the eight IR ranges) and answers a `WheelCommand`. It knows nothing of ROS, so the same object runs in the
pure closed-loop tests and inside the node. Speeds are set as fractions of the course's MAX_SPEED
(6.28 rad/s) and commanded in rad/s, as the course's `setVelocity` does.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from epuck_ros.ir_sensor import LookupTable, range_from_raw
from epuck_ros.model import IR_LOOKUP_TABLE, MAX_WHEEL_SPEED


@dataclass(frozen=True)
class Observation:
    """What a behaviour may read at one tick; `None` = not heard yet."""

    time: float
    odom: tuple[float, float, float] | None = None
    """x (m), y (m), yaw (rad) in the odometry frame."""
    ranges: tuple[float, ...] | None = None
    """ps0..ps7 in metres, inf when nothing is within range (REP 117)."""


FREE_READING_SIGMAS = 3.0
"""A raw reading within this many noise standard deviations of the far end of the lookup table is "nothing seen"."""
_EPUCK_TABLE = LookupTable(IR_LOOKUP_TABLE)
_EPUCK_SEEN_ABOVE = float(IR_LOOKUP_TABLE[-1, 1] * (1.0 + FREE_READING_SIGMAS * IR_LOOKUP_TABLE[-1, 2]))
"""The e-puck's raw value above which a sensor saw something (`ranges_from_raw`), a plain float: compared eight
times a tick."""


def ranges_from_raw(raw: ArrayLike, table: np.ndarray = IR_LOOKUP_TABLE) -> tuple[float, ...]:
    """The ranges a behaviour reads (m, inf = nothing seen, REP 117) from raw sensor values (Webots' getValue()).

    A raw value does not say whether the ray hit anything: a free sensor reads the table's far value (67.19) times
    (1 + 4.9 % noise). A reading up to FREE_READING_SIGMAS standard deviations above that (raw 77.1, 0.0673 m)
    counts as nothing seen, so a free sensor reads inf as on the simulator's `proximity` topic, and the course's
    threshold (raw 80, 0.0665 m) keeps its meaning; beyond it the inverse table as the simulator's own ranges."""
    if table is IR_LOOKUP_TABLE:   # the e-puck's, prepared once
        return tuple(_EPUCK_TABLE.ranges_of([float(value) for value in raw], _EPUCK_SEEN_ABOVE))
    _, far_raw, far_noise = table[-1]
    return tuple(LookupTable(table).ranges_of([float(value) for value in raw],
                                              far_raw * (1.0 + FREE_READING_SIGMAS * far_noise)))


def ranges_from_raw_rows(raw: np.ndarray) -> list[tuple[float, ...]]:
    """`ranges_from_raw` of each row of `raw` (robots x 8, the e-puck's table) in one NumPy pass: a swarm
    controller reads every robot's values at once. The same floats as robot by robot: `LookupTable` computes with the
    array path's arithmetic, operation for operation (test_ir_sensor, test_multi_robot_nodes)."""
    ranges = range_from_raw(raw, raw > _EPUCK_SEEN_ABOVE, IR_LOOKUP_TABLE, _EPUCK_TABLE.inverse)
    return [tuple(row) for row in ranges.tolist()]


@dataclass(frozen=True)
class WheelCommand:
    """Wheel speeds in rad/s."""

    left: float
    right: float

    @classmethod
    def fractions(cls, left: float, right: float) -> WheelCommand:
        """The course's way of writing speeds, a fraction of MAX_SPEED per wheel (0.5, 0.5: half speed)."""
        return cls(left * MAX_WHEEL_SPEED, right * MAX_WHEEL_SPEED)


STOP = WheelCommand(0.0, 0.0)


class ConfigError(ValueError):
    """A behaviour setting is out of range or not one of its choices; the message names it."""


def setting(default: Any, description: str, low: float | None = None, high: float | None = None,
            choices: tuple[str, ...] = ()) -> Any:
    """A config field with what a ROS parameter declaration needs: description, inclusive range, choices."""
    if choices:
        description = f'{description} (one of: {", ".join(choices)})'
    return field(default=default, metadata={'description': description, 'range': (low, high), 'choices': choices})


@dataclass(frozen=True)
class Config:
    """Base of every behaviour's settings; checks each field against its `setting` range and choices."""

    def __post_init__(self) -> None:
        for spec in fields(self):
            value = getattr(self, spec.name)
            low, high = spec.metadata['range']
            choices = spec.metadata['choices']
            if choices and value not in choices:
                raise ConfigError(f'{spec.name} = {value!r}: must be one of {", ".join(choices)}')
            if low is not None and not (low <= value <= high):
                raise ConfigError(f'{spec.name} = {value!r}: must be in [{low}, {high}]')
        self.check()

    def check(self) -> None:
        """Rules across fields; override to add some."""


def describe(config: Config) -> list[tuple[str, Any, str, tuple[Any, Any]]]:
    """(name, value, description, (low, high)) of each setting of `config`, for whoever declares them (the node)."""
    return [(spec.name, getattr(config, spec.name), spec.metadata['description'], spec.metadata['range'])
            for spec in fields(config)]


@dataclass(frozen=True)
class Approach:
    """How to arrive at a distance or an angle without overshooting: cruise, slow down linearly over the last
    `slow_zone`, never below `minimum` (so the target is always reached and the last step is tiny), and stop
    within `tolerance`."""

    slow_zone: float
    minimum: float
    tolerance: float

    def fraction(self, remaining: float, cruise: float) -> float:
        """Speed fraction with the sign of `remaining` (negative = overshot: come back)."""
        magnitude = max(self.minimum, min(cruise, cruise * abs(remaining) / self.slow_zone))
        return math.copysign(magnitude, remaining)

    def arrived(self, remaining: float) -> bool:
        return abs(remaining) <= self.tolerance


DISTANCE_APPROACH = Approach(slow_zone=0.02, minimum=0.02, tolerance=0.0005)
"""Over the last 2 cm down to 0.02 * MAX_SPEED (2.5 mm/s, 0.08 mm per 32 ms step); stop within 0.5 mm.
A full-speed step at 0.5 * MAX_SPEED is 2 mm, so arriving without slowing down would miss by up to that."""

HEADING_APPROACH = Approach(slow_zone=math.radians(20.0), minimum=0.01, tolerance=math.radians(0.15))
"""Over the last 20 degrees down to 0.01 * MAX_SPEED (0.09 degrees per step turning in place); stop within
0.15 degree. Turning in place, both encoders tick together and each pair of ticks turns the odometry yaw by
2 * R/L * 2pi/1000 = 0.28 degree, so the odometry can only land within 0.14 degree of a target: a tighter
tolerance would rock back and forth around it forever."""


class Behaviour(ABC):
    """Observation -> WheelCommand. Until it has heard every input it needs, it commands STOP.

    `state` is a short human-readable description of what it is doing, set by the behaviour only at real
    transitions (a corner reached, the goal reached); `status` is what a node logs when it changes.
    """

    needs_odom: bool = False
    needs_proximity: bool = False

    def __init__(self) -> None:
        self.done = False
        self.state = 'starting'
        self.waiting_for = ''
        """The inputs not heard yet, while there are some."""
        self._last_time: float | None = None
        self.period = 0.0
        """Seconds between the last two ticks (0 until there were two): timed states end on the nearest tick."""

    def update(self, obs: Observation) -> WheelCommand:
        if (self.needs_odom and obs.odom is None) or (self.needs_proximity and obs.ranges is None):
            missing = [name for name, needed, value in (('odom', self.needs_odom, obs.odom),
                                                        ('proximity', self.needs_proximity, obs.ranges))
                       if needed and value is None]
            self.waiting_for = ' and '.join(missing)
            return STOP
        self.waiting_for = ''   # every tick once all is heard: no list built (a headless trial ticks fast)
        if self._last_time is not None:
            self.period = obs.time - self._last_time
        self._last_time = obs.time
        if self.done:
            return STOP
        return self.control(obs)

    @property
    def status(self) -> str:
        return f'waiting for {self.waiting_for}: wheels stopped' if self.waiting_for else self.state

    def elapsed(self, since: float, now: float, duration: float) -> bool:
        """True once `duration` has passed, to the nearest tick: ends a 1 s state after 31 ticks of 32 ms
        (0.992 s), not 32 (1.024 s)."""
        return now - since >= duration - 0.5 * self.period

    @abstractmethod
    def control(self, obs: Observation) -> WheelCommand:
        """The behaviour proper, called only once every needed input is there and while not done."""
