"""The ring of eight IR proximity sensors as a part the steppers compose: rays cast, noisy raw values, ranges.

A sensor part keeps its own readings (one row per robot) and offers the two paired paths the steppers take:
`sense_one` on plain floats for the only robot, `sense_many` on arrays for a swarm, given the robot pairs
close enough to see each other. `reach` tells the swarm stepper how far apart such pairs can be.
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros import ir_sensor
from epuck_ros.model import RobotModel
from epuck_ros.world import World, ray_circle, raycast

SENSE_BLOCK = 512
"""Robots whose rays are cast together (see IrRing.sense_many)."""


class IrRing:
    """The e-puck's eight IR sensors on every robot: one ray each from its pose on the true body.

    `rng` draws the noise (the simulation's only random draw, robot by robot); `noise=False` gives the exact
    table values.
    """

    def __init__(self, world: World, model: RobotModel, count: int, rng: np.random.Generator, noise: bool) -> None:
        self.world, self.model, self.rng, self.noise = world, model, rng, noise
        poses = np.asarray(model.sensor_poses, dtype=float)
        # Each sensor's position on the body, that position turned 90 deg, and its yaw: turned by the robot's yaw
        # each step. As rows (offset x, offset y, left x, left y, yaw) of floats for one robot, and as columns
        # (8, 1) for many robots, whose rays are (8, N) arrays.
        layout = np.column_stack([poses[:, 0], poses[:, 1], -poses[:, 1], poses[:, 0], poses[:, 2]])
        self._rows = layout.tolist()
        self._columns = tuple(column[:, None].copy() for column in layout.T)
        self._cos, self._sin = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])   # (8, 1)
        self._index = np.arange(len(poses))[:, None]
        self._table = ir_sensor.LookupTable(model.ir_table)
        self.reach = float(np.hypot(poses[:, 0], poses[:, 1]).max()) + model.ir_range
        """m from the body's centre beyond which no ray reaches anything: the sensor farthest out plus the ray.
        Farther from every surface, a step casts no rays at all."""
        self.raw = np.empty((count, len(poses)))
        """(N, 8) raw values of ps0..ps7, noisy unless noise is off."""
        self.range = np.empty((count, len(poses)))
        """(N, 8) ranges (m), inf where nothing is within the sensor's range."""

    def sense_one(self, x: float, y: float, yaw: float) -> None:
        """The only robot's rays and readings on Python floats, with `sense_many`'s arithmetic.

        Only the surfaces within `reach` are tested, none when nothing is that near. On arrays of 8, NumPy's
        per-call cost would dominate.
        """
        surfaces = self.world.geometry.surfaces_near(x, y, self.reach)
        distances = None
        if surfaces:
            cos, sin = math.cos(yaw), math.sin(yaw)
            rays = [(x + cos * offset_x + sin * left_x, y + cos * offset_y + sin * left_y,
                     math.cos(yaw + turn), math.sin(yaw + turn))
                    for offset_x, offset_y, left_x, left_y, turn in self._rows]
            distances = raycast.cast_near(self.world.geometry, surfaces, rays, self.model.ir_range)
        sensors = len(self._rows)
        normals = self.rng.standard_normal(sensors).tolist() if self.noise else None
        self.raw[0], self.range[0] = self._table.read_one(distances, normals, sensors)

    def sense_many(self, true: np.ndarray, first: np.ndarray, second: np.ndarray,
                   offsets: np.ndarray | None) -> None:
        """Every robot's rays (true poses (N, 3)) against walls, obstacles and the other robots' bodies.

        `first`, `second`: every pair of robots within `reach` plus a body of each other (and maybe more);
        `offsets`: first's centre minus second's, or None to compute them here. Every part takes the robots (or
        the robots seeing each other) in blocks of SENSE_BLOCK: NumPy's temporaries then stay in the CPU
        cache, and one block is all of them up to 512 robots.
        """
        count = len(true)
        cos, sin = np.cos(true[:, 2]), np.sin(true[:, 2])
        if count <= SENSE_BLOCK:
            distance = np.ascontiguousarray(self._cast(true, slice(0, count), cos, sin))   # see_robots: a flat view
        else:
            distance = np.empty((len(self._rows), count))
            for start in range(0, count, SENSE_BLOCK):
                rows = slice(start, min(start + SENSE_BLOCK, count))
                distance[:, rows] = self._cast(true, rows, cos[rows], sin[rows])
        if offsets is None:
            offsets = true[first, :2] - true[second, :2]
        self._see_robots(distance, cos, sin, first, second, offsets)
        for start in range(0, count, SENSE_BLOCK):   # the noise is drawn robot by robot, as one draw would be
            rows = slice(start, min(start + SENSE_BLOCK, count))
            self._read(rows, distance[:, rows].T.ravel())

    def _cast(self, true: np.ndarray, rows: slice, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
        """Distance (8, n) along each ray of the robots `rows` (cos, sin of their yaws (n,)) to walls and
        obstacles; one row per sensor, so the robots are the long, contiguous axis (see raycast.ray_distances)."""
        x, y, yaw = true[rows, 0], true[rows, 1], true[rows, 2]
        offset_x, offset_y, left_x, left_y, turn = self._columns
        yaws = yaw + turn
        return raycast.ray_distances(self.world.geometry, x + cos * offset_x + sin * left_x,
                                     y + cos * offset_y + sin * left_y, np.cos(yaws), np.sin(yaws),
                                     self.model.ir_range, true[rows, :2], self.reach - self.model.ir_range)

    def _read(self, rows: slice, distance: np.ndarray) -> None:
        """Raw values (noisy unless noise is off) and ranges of the robots `rows` from their ray distances
        (n * 8,), robot by robot."""
        table = self._table
        raw = ir_sensor.noisy_raw(distance, table.table, self.rng if self.noise else None)
        self.raw[rows] = raw.reshape(-1, self.raw.shape[1])
        ranges = ir_sensor.range_from_raw(raw, distance < np.inf, table.table, table.inverse)
        self.range[rows] = ranges.reshape(-1, self.range.shape[1])

    def _see_robots(self, distance: np.ndarray, cos: np.ndarray, sin: np.ndarray, first: np.ndarray,
                    second: np.ndarray, offsets: np.ndarray) -> None:
        """Lower `distance` (8, N) where a ray meets another robot's body first; cos, sin (N,) of the yaws.

        Each close pair gives two viewers (each robot looks at the other), the other's centre turned into the
        viewer's frame, where the viewer's 8 rays are constants: one broadcast (8, viewers) with no per-ray
        gathers. np.minimum.at then keeps each ray's nearest hit, whatever the order of the pairs (no sort).
        """
        dx, dy = offsets[:, 0], offsets[:, 1]
        near = (dx * dx + dy * dy < (self.reach + self.model.body_radius) ** 2).nonzero()[0]
        if not len(near):
            return
        viewer = np.concatenate([second[near], first[near]])   # second sees first at +offset, first sees second at -
        dx, dy = dx[near], dy[near]
        dx, dy = np.concatenate([dx, -dx]), np.concatenate([dy, -dy])
        cos, sin = cos[viewer], sin[viewer]
        local_x, local_y = cos * dx + sin * dy, cos * dy - sin * dx
        offset_x, offset_y, *_ = self._columns
        flat = distance.reshape(-1)
        for start in range(0, len(viewer), SENSE_BLOCK):
            part = slice(start, start + SENSE_BLOCK)
            hits = ray_circle(offset_x, offset_y, self._cos, self._sin, local_x[part], local_y[part],
                              self.model.body_radius)
            hits[hits > self.model.ir_range] = np.inf
            np.minimum.at(flat, (viewer[part] + self._index * len(distance[0])).ravel(), hits.ravel())
