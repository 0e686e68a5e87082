"""The accelerometer and gyro at the body's origin, from the robot's planar motion.

A robot moving at v (m/s) and turning at w (rad/s) feels, in its own frame: forward a_x = dv/dt (over the last
step), sideways a_y = v w (the centripetal acceleration towards the turn's centre), and a_z = g (Webots'
accelerometer measures the reaction to gravity: 9.81 at rest). The gyro turns at (0, 0, w). Both go through the
proto's lookup tables: the accelerometer's is the identity clipped to +-100 m/s^2; the gyro's maps +-13.3 rad/s
to +-100,000.
"""
from __future__ import annotations

import numpy as np

from epuck_ros.model import ACCELEROMETER_LOOKUP_TABLE, GYRO_LOOKUP_TABLE
from epuck_ros.sensors.lookup import lookup

GRAVITY = 9.81
"""m/s^2, Webots' WorldInfo.gravity default."""


def acceleration(twist: np.ndarray, previous_twist: np.ndarray, time_step: float) -> np.ndarray:
    """What an accelerometer at the body's origin feels, in the body frame: an array (R, 3) from the (v, w)
    twists (R, 2) now and one step before."""
    v, w = twist[:, 0], twist[:, 1]
    return np.column_stack([(v - previous_twist[:, 0]) / time_step, v * w, np.full(len(v), GRAVITY)])


def angular_velocity(twist: np.ndarray) -> np.ndarray:
    """(R, 3) rad/s in the body frame."""
    return np.column_stack([np.zeros((len(twist), 2)), twist[:, 1]])


def accelerometer_values(accel: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
    return lookup(accel, ACCELEROMETER_LOOKUP_TABLE, rng)


def gyro_values(rates: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
    return lookup(rates, GYRO_LOOKUP_TABLE, rng)


def rates_from_gyro_values(values: np.ndarray) -> np.ndarray:
    """The gyro's values back in rad/s (the table is linear through 0): what sensor_msgs/Imu carries."""
    return values * (GYRO_LOOKUP_TABLE[-1, 0] / GYRO_LOOKUP_TABLE[-1, 1])
