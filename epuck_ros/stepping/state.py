"""The robots' state as arrays with one row per robot, shared by the simulation and its two steppers."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from epuck_ros.model import RobotModel


@dataclass(eq=False)
class RobotArrays:
    """Every per-robot array the motion and the contact count read and write, (N, ...) each.

    The steppers update them in place (the Simulation's properties hand out these very arrays); the sensor
    parts keep their own readings.
    """

    true: np.ndarray
    """(N, 3) x, y, yaw of the body in the world."""
    odom: np.ndarray
    """(N, 3) the pose integrated from the encoders."""
    true_twist: np.ndarray
    """(N, 2) forward speed and yaw rate the body really had."""
    odom_twist: np.ndarray
    """(N, 2) forward speed and yaw rate from the encoders over the last step."""
    wheel_rotation: np.ndarray
    """(N, 2) exact wheel angles (rad), before the encoders quantise them."""
    encoders: np.ndarray
    """(N, 2) wheel angles as the encoders read them."""
    wheel_speeds: np.ndarray
    """(N, 2) wheel speeds applied in the last step."""
    command: np.ndarray
    """(N, 2) commanded wheel speeds (clamped)."""
    command_twist: np.ndarray
    """(N, 2) (v, w) of each command, kept with it: many robots' steps then need no conversion."""
    touching_obstacle: np.ndarray
    """(N,) bool: the body touches a wall or obstacle."""
    touching_robot: np.ndarray
    """(N,) bool: the body touches another robot."""
    in_contact: np.ndarray
    """(N,) bool: either of the two."""
    collisions: np.ndarray
    """(N,) contacts so far, each counted when it began."""
    robot_collisions: np.ndarray
    """(N,) the contacts with another robot among `collisions`."""

    @classmethod
    def empty(cls, count: int) -> RobotArrays:
        """Arrays for `count` robots: poses, speeds and wheels unset (reset fills them), flags and counts zero."""
        floats = {name: np.empty((count, 3 if name in ('true', 'odom') else 2))
                  for name in ('true', 'odom', 'true_twist', 'odom_twist', 'wheel_rotation', 'encoders',
                               'wheel_speeds', 'command', 'command_twist')}
        flags = {name: np.zeros(count, dtype=bool) for name in ('touching_obstacle', 'touching_robot', 'in_contact')}
        counts = {name: np.zeros(count, dtype=int) for name in ('collisions', 'robot_collisions')}
        return cls(**floats, **flags, **counts)

    def reset(self, start: np.ndarray) -> None:
        """Back to the start poses (N, 3) with odometry, wheels and commands zeroed; contact counts go on."""
        self.true[:] = start
        for state in (self.odom, self.true_twist, self.odom_twist, self.wheel_rotation, self.encoders,
                      self.wheel_speeds, self.command, self.command_twist):
            state.fill(0.0)
        for flags in (self.in_contact, self.touching_obstacle, self.touching_robot):
            flags.fill(False)


def step_travel(model: RobotModel, time_step: float) -> float:
    """Metres the fastest robot covers in one step (both wheels at full speed)."""
    return model.max_wheel_speed * model.wheel_radius * time_step


def substeps(model: RobotModel, time_step: float) -> int:
    """Collision checks per step: never more than half the body radius of travel between two, so nothing
    tunnels through a thin obstacle or another robot even with a long time step (one substep at 32 ms)."""
    return max(1, math.ceil(step_travel(model, time_step) / (0.5 * model.body_radius)))
