"""The ground-sensor extension's gs0..gs2: infra-red distance sensors looking down at the painted floor.

Webots' rule for an infra-red ray (reference manual, DistanceSensor, "Infra-Red Sensors"): the distance is
divided by a reflection factor f = 0.2 + 0.8 * red_level of what the ray hits (roughness and occlusion maps
taken as 0), then looked up in the table. The sensors sit 0.3 mm above the floor: a white floor (f = 1) reads
986.9, black paint (f = 0.2, the distance five times longer) 934.4, noise-free.
"""
from __future__ import annotations

import numpy as np

from epuck_ros.model import GROUND_LOOKUP_TABLE, GROUND_SENSOR_POSES
from epuck_ros.sensors.lookup import lookup
from epuck_ros.sensors.scene import Scene


def reflection_factor(red: np.ndarray) -> np.ndarray:
    return 0.2 + 0.8 * red


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
