"""controller_1: straight ahead at 0.5 * MAX_SPEED, forever or until a goal distance measured on odometry."""
from __future__ import annotations

import math
from dataclasses import dataclass

from epuck_ros.behaviours.base import DISTANCE_APPROACH, STOP, Behaviour, Config, ConfigError, Observation, \
    WheelCommand, setting


@dataclass(frozen=True)
class ForwardConfig(Config):
    speed: float = setting(0.5, 'speed of both wheels, fraction of MAX_SPEED (6.28 rad/s); negative = backwards',
                           -1.0, 1.0)
    goal_distance: float = setting(
        0.0, 'metres to drive, measured on odometry along the start heading, then stop; 0 = drive forever',
        0.0, 100.0)

    def check(self) -> None:
        if self.goal_distance > 0.0 and self.speed == 0.0:
            raise ConfigError('speed = 0.0: the robot can never reach goal_distance; give a non-zero speed')


class Forward(Behaviour):
    """Open loop without a goal (the course's controller_1); with one, progress is the odometry displacement
    projected on the start heading, and the speed ramps down near the goal so the robot stops within 0.5 mm."""

    def __init__(self, config: ForwardConfig) -> None:
        super().__init__()
        self.config = config
        self.needs_odom = config.goal_distance > 0.0
        self.state = f'driving forever at {config.speed:+.2f} x MAX_SPEED'
        self._start: tuple[float, float, float] | None = None
        self.progress = 0.0
        """Metres driven towards the goal so far (odometry)."""

    def control(self, obs: Observation) -> WheelCommand:
        speed = self.config.speed
        if not self.needs_odom:
            return WheelCommand.fractions(speed, speed)
        x, y, _ = obs.odom
        if self._start is None:
            self._start = obs.odom
            self.state = f'driving {self.config.goal_distance:.4f} m'
        x0, y0, yaw0 = self._start
        direction = math.copysign(1.0, speed)
        self.progress = direction * ((x - x0) * math.cos(yaw0) + (y - y0) * math.sin(yaw0))
        remaining = self.config.goal_distance - self.progress
        if DISTANCE_APPROACH.arrived(remaining):
            self.done = True
            self.state = f'goal reached: {self.progress:.4f} m driven on odometry; stopped'
            return STOP
        fraction = direction * DISTANCE_APPROACH.fraction(remaining, abs(speed))
        return WheelCommand.fractions(fraction, fraction)
