"""The e-puck's physical model: geometry, motor limits, encoders, the IR sensor table and the other senses' poses.

Every figure comes from the Webots E-puck.proto (R2022b, ENU frame) and
E-puckDistanceSensor.proto, as collected in ``shared/reference/epuck-model-sources.md``:
wheel radius 0.02 m and axle 0.052 m (§1), maxVelocity 6.28 rad/s, encoder resolution
2π/1000 rad, body collision cylinder radius 0.037 m, sensor poses (§1.1, yaw computed from
the PROTO rotations), the camera's translation, and the IR lookup table (distance m, raw value, relative noise).
The other senses (§6 of the same file, read from E-puck.proto R2022b and E-puckGroundSensors.proto R2020a):
camera, ground sensors, light sensors, accelerometer, gyro, LEDs and the e-puck2's time-of-flight sensor, their
poses on the body (x forward, y left, z up from the floor) and lookup tables, kept here as the one place a URDF or TF
publisher reads them from.
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

BODY_TOP = BODY_CENTRE_HEIGHT + BODY_HEIGHT / 2.0
"""m; the top of the body's collision cylinder: how high other robots' cameras and lights see it."""

CAMERA_WIDTH, CAMERA_HEIGHT = 52, 39
CAMERA_FOV = 0.84
"""rad, horizontal; the vertical field follows from the 4:3 image (square pixels)."""
CAMERA_NEAR = 0.0055
"""m; nothing nearer than this is drawn (Webots' near plane)."""

GROUND_SENSOR_NAMES: tuple[str, ...] = ('gs0', 'gs1', 'gs2')
GROUND_SENSOR_POSES = np.array([[0.03, 0.01, 0.0033], [0.03, 0.0, 0.0033], [0.03, -0.01, 0.0033]])
"""x, y, z (m) of gs0 (left), gs1 (centre), gs2 (right), each looking straight down: the extension slot at
(0.03, 0, 0.0003) (E-puck.proto) and the sensors 1 cm apart, 3 mm above it (E-puckGroundSensors.proto; see
sensors/ground.py for how the two frames compose)."""
GROUND_LOOKUP_TABLE = np.array([[0.0, 1000.0, 0.002], [0.016, 300.0, 0.004]])
"""distance (m), raw value, relative noise: E-puckGroundSensors.proto (R2020a)."""

LIGHT_SENSOR_NAMES: tuple[str, ...] = tuple(f'ls{i}' for i in range(8))
LIGHT_LOOKUP_TABLE = np.array([[1.0, 4095.0, 0.01], [2.0, 0.0, 0.01]])
"""irradiance (W/m^2), raw value, relative noise: more light, lower value, as on the real robot."""

ACCELEROMETER_LOOKUP_TABLE = np.array([[-100.0, -100.0, 0.003], [100.0, 100.0, 0.003]])
"""m/s^2 -> value (the same figure), relative noise; at the body's origin."""
GYRO_LOOKUP_TABLE = np.array([[-13.315805, -100000.0, 0.003], [13.315805, 100000.0, 0.003]])
"""rad/s -> value, relative noise: the proto's gyro returns 7509.9 units per rad/s; at the body's origin."""
IMU_POSITION = (0.0, 0.0, 0.0)
"""x, y, z (m) of the accelerometer and gyro (frame `imu`, axes those of base_link): E-puck.proto gives them no
translation, so they sit at the robot's origin, base_link's (on the floor midway between the wheels)."""

TURRET_SLOT = (-0.0095, 0.0, 0.0486)
"""x, y, z (m) in base_link of the turret slot, where a world's GPS, Compass or InertialUnit sits with the robot's axes:
E-puck.proto's `TURRET_SLOT` Transform (translation -0.0095 0 0.0486, no rotation)."""

TOF_NAME = 'tof'
"""The e-puck2's time-of-flight sensor (a VL53L0X): Webots' DistanceSensor "tof", E-puck.proto when version is "2"."""
TOF_POSE = (0.034, -0.0018, 0.033, -0.0008)
"""x, y, z (m) and yaw (rad) of the ToF's ray in base_link: E-puck.proto's translation 0.034 -0.0018 0.033 and rotation
1 -0.000402 -0.000398 1.570807, which turns the ray (the sensor's local +x) 0.0008 rad to the right and 4e-6 rad up
(computed; the ray is simulated level)."""
TOF_APERTURE = 0.44
"""rad; the proto's `aperture` (type "generic", one ray: the aperture spreads several rays only; the Range's fov)."""
TOF_LOOKUP_TABLE = np.array([
    [0.00, 19.8, 0.126],
    [0.05, 58.5, 0.032],
    [0.10, 111.0, 0.019],
    [0.20, 218.9, 0.009],
    [0.50, 531.9, 0.007],
    [1.00, 1052.0, 0.010],
    [1.70, 1780.5, 0.013],
    [2.00, 2000.0, 0.000],
])
"""distance (m), value, relative noise: E-puck.proto's (version "2"); the ray is as long as the last row, 2 m."""

LED_NAMES: tuple[str, ...] = tuple(f'led{i}' for i in range(10))
LED_POSITIONS = np.array([[0.0337, 0.0, 0.041], [0.022, -0.025, 0.041], [0.0, -0.0337, 0.041],
                          [-0.027, -0.0201, 0.041], [-0.033, 0.0, 0.041], [-0.027, 0.0201, 0.041],
                          [0.0, 0.0337, 0.041], [0.022, 0.025, 0.041], [0.0, 0.0, 0.025], [0.031, -0.0125, 0.0285]])
"""x, y, z (m): led0..led7 on the ring, led8 the body (the whole shell), led9 the front LED."""
LED_COLORS = ((1.0, 0.0, 0.0),) * 8 + ((0.0, 1.0, 0.0), (1.0, 0.3, 0.0))
"""r, g, b of each LED when on: the ring's are Webots' default LED colour (red), led8 green, led9 orange."""


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
