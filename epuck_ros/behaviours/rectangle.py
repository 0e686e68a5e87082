"""controller_4: a rectangle of FORWARD legs and in-place TURNs, the course's two-state machine.

The course turns for a fixed 1 s "to adjust experimentally": at 0.3 * MAX_SPEED that is
R/L * 0.6 * 6.28 = 1.449 rad/s, 83.0 degrees in 1 s of continuous time, so its "rectangle" never closes. In
32 ms steps a turn lasts a whole number of steps: `timed` mode ends it on the step nearest `turn_time` (31 steps,
0.992 s: 82.4 degrees); the course's own program, run unchanged, turns until `elapsed >= 1 s` (32 steps, 1.024 s:
85.0 degrees). `timed` mode keeps that open loop (sides become times: side / speed); `odometry` mode (default)
closes the loop on the odometry pose:
each leg aims at the ideal corner and the ideal heading computed from the start pose, so small errors
do not add up from leg to leg, and the robot slows down near each target to land on it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from epuck_ros.behaviours.base import DISTANCE_APPROACH, HEADING_APPROACH, STOP, Behaviour, Config, \
    ConfigError, Observation, WheelCommand, setting
from epuck_ros.kinematics import wrap_angle
from epuck_ros.model import MAX_WHEEL_SPEED, RobotModel

TURN_MODES = ('odometry', 'timed')
COURSE_SIDE = 5.0 * 0.5 * MAX_WHEEL_SPEED * RobotModel().wheel_radius
"""The course's FORWARD_TIME (5 s) at 0.5 * MAX_SPEED: 0.314 m."""
LEGS_PER_LAP = 8
"""Four sides and four corners."""


@dataclass(frozen=True)
class RectangleConfig(Config):
    side_a: float = setting(COURSE_SIDE, 'length of sides 1 and 3 in metres (timed mode: driven for '
                                         'side_a / speed seconds)', 0.01, 100.0)
    side_b: float = setting(COURSE_SIDE, 'length of sides 2 and 4 in metres', 0.01, 100.0)
    forward_speed: float = setting(0.5, 'wheel speed along the sides, fraction of MAX_SPEED (6.28 rad/s)',
                                   0.01, 1.0)
    turn_speed: float = setting(0.3, 'wheel speed turning in place, fraction of MAX_SPEED; positive turns left '
                                     '(the course: left -0.3, right +0.3), negative turns right', -1.0, 1.0)
    turn_mode: str = setting('odometry', 'how a turn ends: odometry = closed loop on the odometry yaw, true '
                                         '90-degree corners; timed = after turn_time, as the course does',
                             choices=TURN_MODES)
    turn_time: float = setting(1.0, 'seconds per turn in timed mode, ended on the nearest 32 ms step (the course: '
                                    '1 s, 31 steps here: 82.4 degrees; 83.0 in continuous time)',
                               0.01, 60.0)
    laps: int = setting(0, 'laps to drive before stopping; 0 = forever', 0, 1_000_000)

    def check(self) -> None:
        if self.turn_speed == 0.0:
            raise ConfigError('turn_speed = 0.0: the robot could never turn a corner')


class Rectangle(Behaviour):
    """Legs 0, 2, 4, ... are sides, legs 1, 3, 5, ... the corners after them."""

    def __init__(self, config: RectangleConfig, model: RobotModel = RobotModel()) -> None:
        super().__init__()
        self.config = config
        self.needs_odom = config.turn_mode == 'odometry'
        self._turn_sign = math.copysign(1.0, config.turn_speed)
        self._linear_speed = config.forward_speed * model.max_wheel_speed * model.wheel_radius
        self.leg = -1
        self._leg_start = 0.0
        self._corner = (0.0, 0.0)
        """Where the current side starts, ideally (odometry mode)."""
        self._heading = 0.0
        """Heading of the current side, ideally (odometry mode)."""

    def control(self, obs: Observation) -> WheelCommand:
        if self.leg < 0:
            x, y, self._heading = obs.odom or (0.0, 0.0, 0.0)
            self._corner = (x, y)
            self._begin_leg(0, obs.time)
        while (command := self._leg_command(obs)) is None:
            self._finish_leg(obs.time)
            if self.done:
                return STOP
        return command

    def _side_length(self, leg: int) -> float:
        return self.config.side_a if (leg // 2) % 2 == 0 else self.config.side_b

    def _leg_command(self, obs: Observation) -> WheelCommand | None:
        """This tick's command, or None when the current leg is over."""
        config, turning = self.config, self.leg % 2 == 1
        if config.turn_mode == 'timed':
            duration = config.turn_time if turning else self._side_length(self.leg) / self._linear_speed
            if self.elapsed(self._leg_start, obs.time, duration):
                return None
            if turning:
                return WheelCommand.fractions(-config.turn_speed, config.turn_speed)
            return WheelCommand.fractions(config.forward_speed, config.forward_speed)
        x, y, yaw = obs.odom
        if turning:
            error = wrap_angle(self._heading + self._turn_sign * math.pi / 2.0 - yaw)
            if HEADING_APPROACH.arrived(error):
                return None
            fraction = HEADING_APPROACH.fraction(error, abs(config.turn_speed))
            return WheelCommand.fractions(-fraction, fraction)
        travelled = (x - self._corner[0]) * math.cos(self._heading) + (y - self._corner[1]) * math.sin(self._heading)
        remaining = self._side_length(self.leg) - travelled
        if DISTANCE_APPROACH.arrived(remaining):
            return None
        fraction = DISTANCE_APPROACH.fraction(remaining, config.forward_speed)
        return WheelCommand.fractions(fraction, fraction)

    def _finish_leg(self, now: float) -> None:
        if self.leg % 2 == 1:
            self._heading = wrap_angle(self._heading + self._turn_sign * math.pi / 2.0)
        else:
            length = self._side_length(self.leg)
            self._corner = (self._corner[0] + length * math.cos(self._heading),
                            self._corner[1] + length * math.sin(self._heading))
        if self.config.laps and self.leg + 1 == self.config.laps * LEGS_PER_LAP:
            self.done = True
            self.state = f'finished {self.config.laps} lap(s); stopped'
            return
        self._begin_leg(self.leg + 1, now)

    def _begin_leg(self, leg: int, now: float) -> None:
        self.leg, self._leg_start = leg, now
        lap, number = leg // LEGS_PER_LAP + 1, (leg % LEGS_PER_LAP) // 2 + 1
        if leg % 2 == 0:
            action = f'side {number}/4: forward {self._side_length(leg):.3f} m'
        elif self.config.turn_mode == 'timed':
            action = f'corner {number}/4: turning {self._direction} for {self.config.turn_time:.2f} s'
        else:
            action = f'corner {number}/4: turning {self._direction} 90 degrees on odometry'
        self.state = f'lap {lap}, {action}'

    @property
    def _direction(self) -> str:
        return 'left' if self._turn_sign > 0 else 'right'
