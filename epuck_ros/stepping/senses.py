"""The senses beyond the IR ring as one part the simulation composes, each computed only while wanted.

A node (a topic with a subscriber, a Webots controller that enabled the device, a parameter) says which robots
want which sense (`want`); after every step the part reads exactly those, from the new true poses. Nothing is
computed while nobody wants anything, so IR-only runs stay what they were to the bit. A reading's noise depends
on (seed, sense, step, robot) alone (`step_noise`): not on who else wants a sense, nor since when, nor on readings
taken at once when a sense is newly wanted, so a controller reads the same values whoever listens.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from epuck_ros.model import CAMERA_HEIGHT, CAMERA_WIDTH, GROUND_SENSOR_NAMES, LIGHT_SENSOR_NAMES
from epuck_ros.sensors import imu
from epuck_ros.sensors.camera import Camera
from epuck_ros.sensors.ground import GroundSensors
from epuck_ros.sensors.light import LightSensors
from epuck_ros.sensors.lookup import STREAMS
from epuck_ros.sensors.scene import Scene
from epuck_ros.sensors.tof import TofSensor, carried
from epuck_ros.stepping.state import RobotArrays
from epuck_ros.stepping.step_noise import StepNoise
from epuck_ros.world import World

KINDS = ('camera', 'ground', 'light', 'imu', 'tof')


class Senses:
    """Camera images, ground and light raw values, accelerometer and gyro values, ToF values of the robots that want
    them.

    Readings are (N, ...) arrays, NaN (zero for images) in the rows of robots that do not want the sense.
    """

    def __init__(self, world: World, state: RobotArrays, time_step: float, seed: int, noise: bool,
                 camera_size: tuple[int, int] = (CAMERA_WIDTH, CAMERA_HEIGHT), isolated: bool = False) -> None:
        """`isolated`: each robot alone in its own copy of the world (the simulation's option): no robot sees
        another, nor shades its light."""
        count = len(state.true)
        self._isolated = isolated
        self.world, self.count, self.time_step, self.noise = world, count, time_step, noise
        self._state = state
        self._seed = seed
        self._camera_size = camera_size
        self._scene: Scene | None = None
        self._camera: Camera | None = None
        self._ground: GroundSensors | None = None
        self._light: LightSensors | None = None
        self._tof: TofSensor | None = None
        self.step = 0
        """The number of steps the state read has been through (the simulation sets it): the noise's coordinate."""
        self.wanted: dict[str, np.ndarray] = {kind: np.zeros(count, dtype=bool) for kind in KINDS}
        self._rows: dict[str, np.ndarray] = {kind: np.empty(0, dtype=np.int64) for kind in KINDS}
        self.active = False
        """Whether any robot wants any sense: the simulation looks at nothing else while it does not."""
        self.images: np.ndarray | None = None
        """(N, height, width, 3) uint8 RGB, made when a camera is first wanted."""
        self.ground_raw = np.full((count, len(GROUND_SENSOR_NAMES)), np.nan)
        self.light_raw = np.full((count, len(LIGHT_SENSOR_NAMES)), np.nan)
        self.accelerometer = np.full((count, 3), np.nan)
        self.gyro = np.full((count, 3), np.nan)
        self.tof = np.full(count, np.nan)
        """(N,) the ToF's values, as Webots' getValue() returns them (sensors/tof.py)."""
        self._previous_twist: np.ndarray | None = None

    @property
    def scene(self) -> Scene:
        if self._scene is None:   # the floor texture is painted on first use, not for IR-only runs
            self._scene = Scene(self.world, self.world.appearance)
        return self._scene

    @property
    def camera(self) -> Camera:
        if self._camera is None:
            self._camera = Camera(self.scene, *self._camera_size)
        return self._camera

    @property
    def camera_size(self) -> tuple[int, int]:
        """(width, height) of the images."""
        return self._camera_size

    def set_camera_size(self, width: int, height: int) -> None:
        """Another image size (the field of view stays): for those who want more pixels."""
        self._camera_size = (int(width), int(height))
        self._camera = None
        if self.images is not None:
            self.images = np.zeros((self.count, height, width, 3), dtype=np.uint8)

    def want(self, kind: str, robots: Iterable[int], wanted: bool = True) -> None:
        """Start (or stop) reading `kind` for these robots from the next step on."""
        if kind not in KINDS:
            raise ValueError(f'unknown sense {kind!r} (senses: {", ".join(KINDS)})')
        rows = np.fromiter(robots, dtype=np.int64)
        new = rows[~self.wanted[kind][rows]] if wanted else rows[:0]
        self.wanted[kind][rows] = wanted
        self._rows[kind] = np.flatnonzero(self.wanted[kind])
        if kind == 'camera' and self.images is None and self._rows[kind].size:
            width, height = self._camera_size
            self.images = np.zeros((self.count, height, width, 3), dtype=np.uint8)
        self.active = any(rows.size for rows in self._rows.values())
        if new.size:   # readable at once, not only after the next step
            self._read(kind, new, self._state)

    def readings_of(self, robot: int) -> dict[str, Any]:
        """The wanted senses of one robot as a Webots controller's step takes them (`webots.link.StepData.senses`):
        'camera' (H, W, 3) uint8, 'ground' (3 values), 'light' (8), 'imu' (accelerometer (3), gyro values (3)),
        'tof' (the value as the `tof` topic carries it: `tof.carried`)."""
        readings: dict[str, Any] = {}
        if self.wanted['camera'][robot]:
            readings['camera'] = self.images[robot].copy()
        if self.wanted['ground'][robot]:
            readings['ground'] = tuple(self.ground_raw[robot].tolist())
        if self.wanted['light'][robot]:
            readings['light'] = tuple(self.light_raw[robot].tolist())
        if self.wanted['imu'][robot]:
            readings['imu'] = (tuple(self.accelerometer[robot].tolist()), tuple(self.gyro[robot].tolist()))
        if self.wanted['tof'][robot]:
            readings['tof'] = carried(float(self.tof[robot]))
        return readings

    def _noise(self, kind: str, rows: np.ndarray) -> StepNoise | None:
        """The noise of `kind` for these robots at this step (None: exact values)."""
        return StepNoise(self._seed, STREAMS[kind], self.step, rows) if self.noise else None

    def reset(self) -> None:
        """The robots are back at their starts: the wanted senses read there (the IMU from rest)."""
        self._previous_twist = None
        if self.active:
            self.sense(self._state)

    def sense(self, state: RobotArrays) -> None:
        """Read every wanted sense from the state after a step."""
        for kind in KINDS:
            if self._rows[kind].size:
                self._read(kind, self._rows[kind], state)
        if not self._rows['imu'].size:
            self._previous_twist = None

    def _read(self, kind: str, rows: np.ndarray, state: RobotArrays) -> None:
        true = state.true
        others = true[:, :2] if self.count > 1 and not self._isolated else None
        if kind == 'ground':
            if self._ground is None:
                self._ground = GroundSensors(self.scene)
            self.ground_raw[rows] = self._ground.read(true[rows], self._noise('ground', rows))
        elif kind == 'light':
            if self._light is None:
                self._light = LightSensors(self.scene)
            self.light_raw[rows] = self._light.read(true[rows], self._noise('light', rows), others, rows)
        elif kind == 'imu':
            twist = state.true_twist
            previous = twist if self._previous_twist is None else self._previous_twist
            self.accelerometer[rows] = imu.accelerometer_values(
                imu.acceleration(twist[rows], previous[rows], self.time_step), self._noise('accelerometer', rows))
            self.gyro[rows] = imu.gyro_values(imu.angular_velocity(twist[rows]), self._noise('gyro', rows))
            self._previous_twist = twist.copy()
        elif kind == 'tof':
            if self._tof is None:
                self._tof = TofSensor(self.world)
            scene = self.scene if others is not None else None
            self.tof[rows] = self._tof.read(true[rows], self._noise('tof', rows), scene, others, rows)
        else:
            self.images[rows] = self.camera.render(true[rows], others, rows)
