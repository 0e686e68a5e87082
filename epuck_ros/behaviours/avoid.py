"""Obstacle avoidance: the course's rules on the IR ranges, or Webots' e-puck_avoid_obstacles Braitenberg weights.

Rules (the course's listing, with two corrections):
- any front sensor (ps0, ps1, ps6, ps7) closer than `threshold` -> turn in place. The turn picks its
  direction once, away from the nearer front side, and keeps it until every front sensor reads at least
  `release_distance` (hysteresis): re-deciding every tick makes the robot rock between two walls of a corner;
- else an obstacle on one side only (ps2 right, ps5 left) -> veer AWAY from it (the course's listing slows
  the wheel on the far side, which steers towards the obstacle);
- else cruise straight.
The course's threshold is the raw value 80, which the inverse lookup table turns into 0.0665 m.

Braitenberg (Webots' default e-puck controller): each wheel = 0.5 * MAX_SPEED + sum(w * raw / 4096) * MAX_SPEED,
clipped; it works on raw values, so ranges go back through the table (inf -> the table's far value, 67.19).
The same front escape turn overrides it: raw / 4096 stays below 0.1 until an obstacle is within 2 cm of a
sensor, and the sensors sit 3 to 6 mm inside the body's edge, so the weights alone react too late and the robot
touches the boxes of the default world (the README gives the count).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from epuck_ros.behaviours.base import Behaviour, Config, ConfigError, Observation, WheelCommand, setting
from epuck_ros.ir_sensor import distance_from_raw, raw_from_distance
from epuck_ros.model import FRONT_SENSORS, IR_LOOKUP_TABLE

MODES = ('rules', 'braitenberg')
COURSE_THRESHOLD = float(distance_from_raw(80.0, IR_LOOKUP_TABLE))
"""The course's THRESHOLD = 80 (raw) as a distance: 0.0665 m."""
RIGHT_SIDE, LEFT_SIDE = 2, 5
FRONT_RIGHT, FRONT_LEFT = (0, 1), (7, 6)

BRAITENBERG_WEIGHTS = np.array([
    [-1.3, -1.0], [-1.3, -1.0], [-0.5, 0.5], [0.0, 0.0],
    [0.0, 0.0], [0.05, -0.5], [-0.75, 0.0], [-0.75, 0.0],
])
"""Rows ps0..ps7, columns (left, right) wheel: Webots e-puck_avoid_obstacles.c."""
BRAITENBERG_RAW_SCALE = 4096.0


@dataclass(frozen=True)
class AvoidConfig(Config):
    mode: str = setting('rules', "rules = the course's if/else on ranges; braitenberg = Webots' default "
                                 'e-puck controller', choices=MODES)
    threshold: float = setting(COURSE_THRESHOLD, 'an obstacle is closer than this (m); the default is '
                                                 "the course's raw value 80 through the lookup table", 0.0, 0.07)
    release_distance: float = setting(0.07, 'a turn away from a front obstacle goes on until every front '
                                            'sensor reads at least this far (m); 0.07 = sees nothing', 0.0, 0.07)
    cruise_speed: float = setting(0.5, 'speed of both wheels when the way is clear, fraction of MAX_SPEED '
                                       '(braitenberg: the offset both wheels start from)', -1.0, 1.0)
    turn_speed: float = setting(0.4, 'wheel speed turning in place away from a front obstacle, '
                                     'fraction of MAX_SPEED', 0.01, 1.0)
    veer_speed: float = setting(0.2, 'rules: speed of the wheel on the obstacle-free side when veering away '
                                     'from a side obstacle (the other wheel keeps cruise_speed)', -1.0, 1.0)

    def check(self) -> None:
        if self.release_distance < self.threshold:
            raise ConfigError(f'release_distance = {self.release_distance}: must be at least threshold = '
                              f'{self.threshold}, or a turn would stop while the obstacle is still too close')


class Avoid(Behaviour):
    needs_proximity = True

    def __init__(self, config: AvoidConfig) -> None:
        super().__init__()
        self.config = config
        self.turning = 0
        """+1 turning left, -1 turning right, 0 not turning away from a front obstacle."""
        self._cruise_state = 'cruising' if config.mode == 'rules' else 'cruising on the Braitenberg weights'
        self.state = self._cruise_state

    def control(self, obs: Observation) -> WheelCommand:
        # Plain floats, as np.asarray(ranges, dtype=float) would hold them: eight values a tick are too few for
        # NumPy to pay its per-call cost (a headless trial ticks thousands of times a second).
        ranges = [float(value) for value in obs.ranges]
        config = self.config
        self._update_escape(ranges)
        if self.turning:
            return WheelCommand.fractions(-self.turning * config.turn_speed, self.turning * config.turn_speed)
        if config.mode == 'braitenberg':
            return braitenberg(np.asarray(ranges), config.cruise_speed)
        return self._veer(ranges)

    def _update_escape(self, ranges: list[float]) -> None:
        """Start turning in place when the front is blocked, stop once it is clear (hysteresis)."""
        front = _least(ranges, FRONT_SENSORS)
        if self.turning and front >= self.config.release_distance:
            self.turning = 0
            self.state = self._cruise_state
        elif not self.turning and front < self.config.threshold:
            self.turning = 1 if _least(ranges, FRONT_RIGHT) <= _least(ranges, FRONT_LEFT) else -1
            self.state = f'front obstacle: turning {"left" if self.turning > 0 else "right"} until clear'

    def _veer(self, ranges: list[float]) -> WheelCommand:
        config = self.config
        right, left = ranges[RIGHT_SIDE] < config.threshold, ranges[LEFT_SIDE] < config.threshold
        if right and not left:
            return WheelCommand.fractions(config.veer_speed, config.cruise_speed)
        if left and not right:
            return WheelCommand.fractions(config.cruise_speed, config.veer_speed)
        return WheelCommand.fractions(config.cruise_speed, config.cruise_speed)


def _least(ranges: list[float], sensors: tuple[int, ...]) -> float:
    """The least of `ranges` at `sensors`, NaN if one of them is (as NumPy's min)."""
    values = [ranges[sensor] for sensor in sensors]
    return math.nan if any(map(math.isnan, values)) else min(values)


def braitenberg(ranges: np.ndarray, offset: float) -> WheelCommand:
    """Webots' e-puck_avoid_obstacles on ranges: raw values back through the table, weighted, clipped."""
    raw = raw_from_distance(np.minimum(ranges, IR_LOOKUP_TABLE[-1, 0]), IR_LOOKUP_TABLE)
    left, right = np.clip(offset + (raw / BRAITENBERG_RAW_SCALE) @ BRAITENBERG_WEIGHTS, -1.0, 1.0)
    return WheelCommand.fractions(float(left), float(right))
