"""The light sensors ls0..ls7: irradiance from the world's point lights, through the proto's lookup table.

Webots' LightSensor (reference manual, lightsensor.md): each light adds intensity x attenuation x max(0, N.L),
N the sensor's axis, L the unit vector to the light, unless an obstacle hides the light (the `occlusion` option,
on here); lights are white and ambientIntensity 0, so E is that sum. Attenuation is 1 / d^2 (see
epuck_ros.world.appearance). An obstacle hides a light when the sight line passes below its top where it crosses it;
robots' bodies hide light too. The table maps E = 1 W/m^2 and less to 4095 and E = 2 and more to 0.
"""
from __future__ import annotations

import numpy as np

from epuck_ros.model import LIGHT_LOOKUP_TABLE, LIGHT_SENSOR_HEIGHT, SENSOR_POSES, BODY_TOP
from epuck_ros.sensors.lookup import lookup
from epuck_ros.sensors.scene import Scene


class LightSensors:
    """Irradiance and raw values (R, 8) of ls0..ls7 for robots at given poses."""

    def __init__(self, scene: Scene, table: np.ndarray = LIGHT_LOOKUP_TABLE) -> None:
        self.scene, self.table = scene, table
        lights = scene.appearance.lights
        self._lights = np.array([[light.x, light.y, light.z, light.intensity] for light in lights]).reshape(-1, 4)
        self._px, self._py, self._yaw = (SENSOR_POSES[:, k] for k in range(3))

    def irradiance(self, poses: np.ndarray, robots_xy: np.ndarray | None = None,
                   own: np.ndarray | None = None) -> np.ndarray:
        """E (R, 8) in W/m^2; `robots_xy` (N, 2) and `own` as for the camera (bodies that cast shadows)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        count = len(poses)
        total = np.zeros((count, len(self._px)))
        if not len(self._lights):
            return total
        cos, sin = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
        sx = poses[:, 0:1] + cos * self._px - sin * self._py                 # (R, 8)
        sy = poses[:, 1:2] + sin * self._px + cos * self._py
        axis = poses[:, 2:3] + self._yaw
        nx, ny = np.cos(axis), np.sin(axis)
        for lx, ly, lz, intensity in self._lights.tolist():
            vx, vy, vz = lx - sx, ly - sy, lz - LIGHT_SENSOR_HEIGHT
            flat = np.hypot(vx, vy)
            distance2 = flat * flat + vz * vz
            facing = np.maximum(0.0, (nx * vx + ny * vy) / np.sqrt(distance2))
            lit = facing > 0.0
            if lit.any():
                lit &= ~self._occluded(sx, sy, vx, vy, flat, lz, robots_xy, own, count)
            total += np.where(lit, intensity * facing / distance2, 0.0)
        return total

    def _occluded(self, sx: np.ndarray, sy: np.ndarray, vx: np.ndarray, vy: np.ndarray, flat: np.ndarray,
                  lz: float, robots_xy: np.ndarray | None, own: np.ndarray | None, count: int) -> np.ndarray:
        """(R, 8): an obstacle stands in the sight line from each sensor to the light (x, y, lz)."""
        # A ray that hits nothing has t = inf and a light straight above has flat = 0: their sight-line heights are
        # NaN (inf * 0, 0 / 0), and NaN compares False, so neither blocks, as it should.
        with np.errstate(invalid='ignore', divide='ignore'):
            dx, dy = vx / flat, vy / flat
            # one origin per (robot, sensor): rays (R*8, 1)
            ox, oy = sx.reshape(-1, 1), sy.reshape(-1, 1)
            dxr, dyr = dx.reshape(-1, 1), dy.reshape(-1, 1)
            reach = flat.reshape(-1, 1)
            t = self.scene.hits(ox, oy, dxr, dyr)                            # (objects, R*8, 1)
            line = LIGHT_SENSOR_HEIGHT + (lz - LIGHT_SENSOR_HEIGHT) * t / reach
            heights = self.scene.heights[:len(t)].reshape(-1, 1, 1)
            blocked = ((t < reach) & (heights > line)).any(axis=0)[:, 0]
            blocked = blocked.reshape(count, -1)
            if robots_xy is not None and len(robots_xy) > 1:
                t_robot = self.scene.robot_hits(sx, sy, dx, dy, np.asarray(robots_xy, dtype=float),
                                                np.arange(count) if own is None else np.asarray(own))
                line = LIGHT_SENSOR_HEIGHT + (lz - LIGHT_SENSOR_HEIGHT) * t_robot / flat
                blocked |= (t_robot < flat) & (BODY_TOP > line)
            return blocked

    def read(self, poses: np.ndarray, rng: np.random.Generator | None, robots_xy: np.ndarray | None = None,
             own: np.ndarray | None = None) -> np.ndarray:
        return lookup(self.irradiance(poses, robots_xy, own), self.table, rng)
