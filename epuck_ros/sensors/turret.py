"""What a GPS, Compass and InertialUnit in the e-puck's turret slot return, as Webots computes them.

Webots (cyberbotics/webots, src/webots/nodes/WbGps.cpp, WbCompass.cpp, WbInertialUnit.cpp, the controller library's
inertial_unit.c, docs/reference/gps.md, compass.md, inertialunit.md, worldinfo.md), for WorldInfo's defaults
(coordinateSystem "ENU": x east, y north, z up; gpsCoordinateSystem "local", gpsReference 0 0 0; no noise):

- GPS `getValues()`: the device's position in the world (m); `getSpeedVector()`: its velocity in the world (m/s; the
  body's velocity at the device's point); `getSpeed()`: that vector's length.
- Compass `getValues()`: the north vector (0, 1, 0) in the device's frame.
- InertialUnit `getQuaternion()`: the device's rotation in the world, [x, y, z, w]; `getRollPitchYaw()`: its
  roll, pitch and yaw (ENU: the x-y-z extrinsic sequence), yaw 0 facing +x (east), counter-clockwise positive.

The devices sit in the turret slot (`model.TURRET_SLOT`, 4.86 cm up, 9.5 mm behind the axle) with the robot's axes. A
robot here moves in the plane: everything follows from its true pose and twist as the `ground_truth` topic carries
them, `Truth` (x, y, the orientation quaternion's z and w, v, w), so a controller over ROS and a headless one compute
the same numbers from the same floats.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from epuck_ros.conversions import quaternion_from_yaw
from epuck_ros.model import TURRET_SLOT


class Truth(NamedTuple):
    """A robot's true planar state, as the simulator's `ground_truth` Odometry carries it."""

    x: float
    y: float
    qz: float
    qw: float
    v: float
    w: float

    @classmethod
    def of(cls, pose: tuple[float, float, float], twist: tuple[float, float]) -> Truth:
        """From a pose (x, y, yaw) and twist (v, w), with the quaternion the topic carries (`quaternion_from_yaw`)."""
        x, y, yaw = pose
        return cls(float(x), float(y), *quaternion_from_yaw(float(yaw)), float(twist[0]), float(twist[1]))

    def heading(self) -> tuple[float, float]:
        """(cos, sin) of the yaw, from the quaternion."""
        return 1.0 - 2.0 * self.qz * self.qz, 2.0 * self.qz * self.qw


def gps_values(truth: Truth) -> list[float]:
    cos, sin = truth.heading()
    sx, sy, sz = TURRET_SLOT
    return [truth.x + cos * sx - sin * sy, truth.y + sin * sx + cos * sy, sz]


def gps_speed_vector(truth: Truth) -> list[float]:
    """The slot's velocity: v along the heading plus w x r, r the slot's offset turned with the robot."""
    cos, sin = truth.heading()
    sx, sy, _ = TURRET_SLOT
    rx, ry = cos * sx - sin * sy, sin * sx + cos * sy
    return [truth.v * cos - truth.w * ry, truth.v * sin + truth.w * rx, 0.0]


def compass_values(truth: Truth) -> list[float]:
    """The world's north (0, 1, 0) turned into the robot's frame: (sin yaw, cos yaw, 0)."""
    cos, sin = truth.heading()
    return [sin, cos, 0.0]


def quaternion(truth: Truth) -> list[float]:
    """[x, y, z, w], Webots' order."""
    return [0.0, 0.0, truth.qz, truth.qw]


def roll_pitch_yaw(truth: Truth) -> list[float]:
    """The controller library's ENU conversion of the quaternion (inertial_unit.c)."""
    x, y, z, w = quaternion(truth)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return [roll, pitch, yaw]
