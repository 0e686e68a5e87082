"""The ground-sensor extension's gs0..gs2: infra-red distance sensors looking down at the painted floor.

What Webots computes, and where each figure comes from (cyberbotics/webots):

- Where the sensors are. E-puckGroundSensors.proto (R2020a, the newest stored copy) puts gs0, gs1, gs2 at
  x = -0.01, 0, 0.01 and 0.003 m along the module's up axis (its frame is the robot's: the slot's rotation and the
  module's cancel), each turned so that its ray points down; E-puck.proto's ground-sensor slot adds 0.0003 m of
  height and 0.03 m forward (R2019 NUE copy `0 0.0003 -0.03`, R2022b ENU copy `0.03 0 0.0003`). So the sensors
  look down from 3.3 mm, 3 cm ahead of the axle (`model.GROUND_SENSOR_POSES`). We had read the module's 3 mm as a
  step back and left the sensors 0.3 mm above the floor: white read 987, black 934, and Webots' programs never
  saw a line.
- The rule. src/webots/nodes/WbDistanceSensor.cpp (computeValue, INFRA_RED) and the reference manual
  (distancesensor.md, "Infra-Red Sensors"): the distance the ray travels is divided by the reflection factor
  f = 0.2 + 0.8 * red * (1 - 0.5 * roughness) * (1 - 0.5 * occlusion) of what it hits (red: the red level of its
  colour or texture pixel; roughness: its PBRAppearance's; occlusion: its occlusion map's, none here), then
  looked up in the table [0 m: 1000, 0.016 m: 300] (E-puckGroundSensors.proto; noise 0.002 and 0.004).
- The floor. Webots' e-puck line worlds (projects/robots/gctronic/e-puck/worlds/e-puck_line.wbt,
  e-puck_line_demo.wbt) give the arena's floor a PBRAppearance with roughness 0.2 and metalness 0: every floor
  here is that floor (`FLOOR_ROUGHNESS`).

So a white floor reads 1000 - 700 * (0.0033 / 0.92) / 0.016 = 843.1 and black paint (f = 0.2: 16.5 mm, past the
table's end) 300, noise-free: what controllers/e-puck_line_demo/e-puck_line_demo.c expects (white above
LLM_THRESHOLD 800, the line below LEM_THRESHOLD 500, GS_WHITE 900 a little above white). Red paint reads as white,
as in Webots: the infra-red rule sees the red channel only.
"""
from __future__ import annotations

import numpy as np

from epuck_ros.model import GROUND_LOOKUP_TABLE, GROUND_SENSOR_POSES
from epuck_ros.sensors.lookup import lookup
from epuck_ros.sensors.scene import Scene

FLOOR_ROUGHNESS = 0.2
"""The PBRAppearance roughness of the floor of Webots' e-puck line worlds (e-puck_line.wbt, e-puck_line_demo.wbt)."""


def reflection_factor(red: np.ndarray, roughness: float = FLOOR_ROUGHNESS, occlusion: float = 0.0) -> np.ndarray:
    """Webots' infra-red reflection factor of a surface of red level `red` (WbDistanceSensor.cpp)."""
    return 0.8 * red * (1.0 - 0.5 * roughness) * (1.0 - 0.5 * occlusion) + 0.2


class GroundSensors:
    """Raw values (R, 3) of gs0..gs2 for robots at given poses."""

    def __init__(self, scene: Scene, table: np.ndarray = GROUND_LOOKUP_TABLE) -> None:
        self.scene, self.table = scene, table
        self._x, self._y, self._z = (GROUND_SENSOR_POSES[:, k] for k in range(3))

    def read(self, poses: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        cos, sin = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
        x = poses[:, 0:1] + cos * self._x - sin * self._y
        y = poses[:, 1:2] + sin * self._x + cos * self._y
        floor = self.scene.floor
        red = floor.red[floor.index(x, y)]
        return lookup(self._z / reflection_factor(red), self.table, rng)
