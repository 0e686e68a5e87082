"""Differential-drive kinematics: wheel speeds <-> twist, the per-wheel clamp, exact-arc integration, encoders.

Every function takes floats or NumPy arrays of any (matching) shape, so the simulator steps N robots with the
same calls it uses for one. The formulas are the course's: v = R/2 (wR + wL), w = R/L (wR - wL).
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from epuck_ros.model import RobotModel


_SCALAR = (float, int)


def twist_from_wheels(left: ArrayLike, right: ArrayLike, model: RobotModel) -> tuple[ArrayLike, ArrayLike]:
    """Forward speed (m/s) and yaw rate (rad/s) from the wheel speeds (rad/s)."""
    v = 0.5 * model.wheel_radius * (right + left)
    w = model.wheel_radius / model.wheel_separation * (right - left)
    return v, w


def wheels_from_twist(v: ArrayLike, w: ArrayLike, model: RobotModel) -> tuple[ArrayLike, ArrayLike]:
    """Wheel speeds (rad/s) that produce forward speed `v` (m/s) and yaw rate `w` (rad/s); the inverse of the above."""
    half_axle_w = 0.5 * model.wheel_separation * w
    return (v - half_axle_w) / model.wheel_radius, (v + half_axle_w) / model.wheel_radius


def clamp_wheels(left: ArrayLike, right: ArrayLike, max_speed: float) -> tuple[ArrayLike, ArrayLike]:
    """Clamp each wheel to +-max_speed on its own, as Webots' motors do (so saturation changes the curvature).

    Two floats (a command) are clamped with min/max: np.clip costs more than the rest of a command on a Python
    float, and a command arrives with every lockstep step."""
    if isinstance(left, float) and isinstance(right, float):
        return min(max(left, -max_speed), max_speed), min(max(right, -max_speed), max_speed)
    return np.clip(left, -max_speed, max_speed), np.clip(right, -max_speed, max_speed)


def integrate_arc(x: ArrayLike, y: ArrayLike, yaw: ArrayLike, v: ArrayLike, w: ArrayLike,
                  dt: float) -> tuple[ArrayLike, ArrayLike, ArrayLike]:
    """Pose after moving for `dt` at constant (v, w): the exact circular arc, yaw wrapped to [-pi, pi).

    The arc's chord has length v*dt*sin(h)/h (h = w*dt/2) and points along the mid-step heading yaw + h; this
    equals the usual x += v/w (sin(yaw1) - sin(yaw0)) form but never divides by w. sin(h)/h is exactly 1 for
    |h| < 1e-8 in double precision, so the straight-line limit needs no threshold and cannot blow up.
    """
    half_turn = 0.5 * w * dt
    if (isinstance(half_turn, float) and isinstance(x, _SCALAR) and isinstance(y, _SCALAR)
            and isinstance(yaw, _SCALAR) and isinstance(v, _SCALAR)):
        # one robot: math on floats is much cheaper than NumPy calls on scalars
        shrink = math.sin(half_turn) / half_turn if half_turn else 1.0
        cos, sin = math.cos, math.sin
    else:   # any array (pose or speeds) broadcasts against the rest
        shrink = np.sinc(np.divide(half_turn, math.pi))
        cos, sin = np.cos, np.sin
    chord = v * dt * shrink
    heading = yaw + half_turn
    return x + chord * cos(heading), y + chord * sin(heading), wrap_angle(yaw + 2.0 * half_turn)


def wrap_angle(angle: ArrayLike) -> ArrayLike:
    """Angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def quantise(angle: ArrayLike, resolution: float) -> ArrayLike:
    """An encoder's reading: the angle rounded to the nearest multiple of `resolution` (Webots PositionSensor).

    Ties round to even either way (Python's round and np.rint agree); floats skip NumPy's per-call cost.
    """
    if isinstance(angle, float):
        return round(angle / resolution) * resolution
    return np.rint(np.divide(angle, resolution)) * resolution
