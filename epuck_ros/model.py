"""The e-puck's physical model: geometry, motor limits, encoders and IR sensor table.

Every figure comes from the Webots E-puck.proto (R2022b, ENU frame) and
E-puckDistanceSensor.proto, as collected in ``shared/reference/epuck-model-sources.md``:
wheel radius 0.02 m and axle 0.052 m (§1), maxVelocity 6.28 rad/s, encoder resolution
2π/1000 rad, body collision cylinder radius 0.037 m, sensor poses (§1.1, yaw computed from
the PROTO rotations), the camera's translation, and the IR lookup table (distance m, raw value, relative noise).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

MAX_WHEEL_SPEED = 6.28
"""rad/s; the course's MAX_SPEED and Webots' motor maxVelocity (v1)."""

TIME_STEP = 0.032
"""s; Webots' basicTimeStep for the e-puck worlds: one simulator step, and one step of the course's controllers."""

SENSOR_NAMES: tuple[str, ...] = tuple(f'ps{i}' for i in range(8))
FRONT_SENSORS: tuple[int, ...] = (0, 1, 6, 7)
"""The sensors the course's obstacle avoidance treats as "in front"."""

# x (m), y (m), yaw (rad) of ps0..ps7 in base_link (x forward, y left, yaw CCW).
SENSOR_POSES = np.array([
    [0.030, -0.010, -0.3008],
    [0.022, -0.025, -0.8008],
    [0.000, -0.031, -1.5708],
    [-0.030, -0.015, -2.6440],
    [-0.030, 0.015, 2.6392],
    [0.000, 0.031, 1.5708],
    [0.022, 0.025, 0.7992],
    [0.030, 0.010, 0.2992],
])

SENSOR_HEIGHT = 0.033
"""m above the floor of ps0..ps7 (the z of their translations); their rays are simulated level."""
LIGHT_SENSOR_HEIGHT = 0.0329
"""m above the floor of ls0..ls7, which share the x, y and yaw of ps0..ps7."""
CAMERA_POSE = (0.030, 0.0, 0.028)
"""x, y, z (m) of the camera in base_link, looking along +x."""
BODY_HEIGHT = 0.045
BODY_CENTRE_HEIGHT = 0.025
"""m; the body's collision cylinder (radius `RobotModel.body_radius`) and the height of its centre."""
WHEEL_WIDTH = 0.005
"""m; the wheel's bounding cylinder (its hinge sits at the wheel radius above the floor)."""

# Webots E-puckDistanceSensor lookupTable: distance (m), raw value, relative noise (std).
IR_LOOKUP_TABLE = np.array([
    [0.000, 4095.0, 0.002],
    [0.005, 2133.33, 0.003],
    [0.010, 1465.73, 0.007],
    [0.015, 601.46, 0.0406],
    [0.020, 383.84, 0.01472],
    [0.030, 234.93, 0.0241],
    [0.040, 158.03, 0.0287],
    [0.050, 120.0, 0.04225],
    [0.060, 104.09, 0.03065],
    [0.070, 67.19, 0.04897],
])


@dataclass(frozen=True, eq=False)
class RobotModel:
    """Geometry and limits of one e-puck; the defaults are the Webots model's.

    The two tables are NumPy arrays (the sensors index them), made read-only so the frozen model stays
    unchanged; equality and hashing compare their values (the generated ones would compare arrays by truth
    value and raise).
    """

    wheel_radius: float = 0.020
    wheel_separation: float = 0.052
    max_wheel_speed: float = MAX_WHEEL_SPEED
    body_radius: float = 0.037
    encoder_resolution: float = 2.0 * math.pi / 1000.0
    ir_range: float = 0.07
    ir_aperture: float = 0.1
    sensor_poses: np.ndarray = field(default_factory=lambda: SENSOR_POSES.copy())
    ir_table: np.ndarray = field(default_factory=lambda: IR_LOOKUP_TABLE.copy())

    def __post_init__(self) -> None:
        for name in ('sensor_poses', 'ir_table'):
            table = np.array(getattr(self, name), dtype=float)
            table.setflags(write=False)
            object.__setattr__(self, name, table)

    def _key(self) -> tuple:
        return tuple(getattr(self, f.name).tobytes() + str(getattr(self, f.name).shape).encode()
                     if isinstance(getattr(self, f.name), np.ndarray) else getattr(self, f.name)
                     for f in fields(self))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RobotModel):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())
