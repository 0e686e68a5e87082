"""The e-puck2's time-of-flight sensor `tof`: one ray straight ahead, Webots' "generic" DistanceSensor.

What Webots computes (cyberbotics/webots, E-puck.proto when version is "2", distancesensor.md): one ray
(`numberOfRays` 1: the 0.44 rad aperture spreads several rays only) from (0.034, -0.0018, 0.033) along the robot's
heading, as long as the table's last distance (2 m); the distance to the first thing it meets goes through the
proto's lookup table [0 m: 19.8 ... 2 m: 2000] with its relative noise; nothing within 2 m reads the last row, 2000
(noise 0 there). A "generic" sensor has no reflection factor: colour does not matter. The ray meets walls, obstacles
and other robots' bodies, in the floor plane, as the IR rays do (ir_sensor.py).

What the e-puck's ROS interface carries (webots_ros2_driver Ros2DistanceSensor.cpp, Math.cpp): a sensor_msgs/Range
whose range is the value back through the table (`range_from_value`: piecewise linear, extrapolated beyond both
ends, not clipped), radiation type INFRARED (that plugin's for every distance sensor), field of view the aperture,
min_range / max_range the table's end distances moved in by their noise (`RANGE_LIMITS`: 0 and 2 m). A Webots
controller over ROS gets its getValue() back from that float32 range (`carried`), and a headless one the same.
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.ir_sensor import distance_from_raw
from epuck_ros.model import TOF_LOOKUP_TABLE, TOF_POSE, RobotModel
from epuck_ros.sensors.lookup import lookup
from epuck_ros.sensors.scene import Scene
from epuck_ros.world import World


def range_limits(table: np.ndarray) -> tuple[float, float]:
    """(min_range, max_range) of the Range message as Ros2DistanceSensor.cpp sets them from a lookup table: the end
    rows' distances, each moved inwards by its noise (relative noise x distance)."""
    near, far = (table[0], table[-1]) if table[0, 0] < table[-1, 0] else (table[-1], table[0])
    return float(near[0] + near[2] * near[0]), float(far[0] - far[2] * far[0])


RANGE_LIMITS = range_limits(TOF_LOOKUP_TABLE)
"""(min_range, max_range) of the `tof` topic's Range: (0.0, 2.0)."""
MAX_DISTANCE = float(TOF_LOOKUP_TABLE[-1, 0])
"""m; how far the ray reaches: the table's last distance."""


def range_from_value(values: np.ndarray | float) -> np.ndarray:
    """The Range's range (m) of ToF values: the inverse lookup table, extrapolated beyond its ends (Math.cpp)."""
    return distance_from_raw(values, TOF_LOOKUP_TABLE)


def value_from_range(ranges: np.ndarray | float) -> np.ndarray:
    """The value a range came from: `range_from_value`'s inverse, extrapolated beyond the table as it is."""
    distances, values = TOF_LOOKUP_TABLE[:, 0], TOF_LOOKUP_TABLE[:, 1]
    ranges = np.asarray(ranges, dtype=float)
    low = values[0] + (ranges - distances[0]) * (values[1] - values[0]) / (distances[1] - distances[0])
    high = values[-1] + (ranges - distances[-1]) * (values[-1] - values[-2]) / (distances[-1] - distances[-2])
    return np.where(ranges < distances[0], low, np.where(ranges > distances[-1], high,
                                                         np.interp(ranges, distances, values)))


def carried(value: float) -> float:
    """A value as a controller gets it through the `tof` topic: its range in float32 (the Range's type), and back.
    Within a few units in the last place of float32; the headless path hands scripts the same, so a script reads the
    same numbers over ROS and headless."""
    return float(value_from_range(float(np.float32(range_from_value(value)))))


class TofSensor:
    """Values (R,) of the ToF of robots at given poses."""

    def __init__(self, world: World, model: RobotModel = RobotModel()) -> None:
        self.world, self.model = world, model
        self._x, self._y, _, self._yaw = TOF_POSE
        self.reach = math.hypot(self._x, self._y) + MAX_DISTANCE + model.body_radius
        """m between two robots' centres beyond which one's ToF cannot meet the other's body."""

    def distances(self, poses: np.ndarray, scene: Scene | None = None, robots_xy: np.ndarray | None = None,
                  own: np.ndarray | None = None) -> np.ndarray:
        """Distance (R,) along each robot's ray to the first wall, obstacle or (with `scene`, `robots_xy` (N, 2) and
        each viewer's row `own` (R,)) other robot's body; inf when nothing is within MAX_DISTANCE."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        ox = poses[:, 0] + cos * self._x - sin * self._y
        oy = poses[:, 1] + sin * self._x + cos * self._y
        heading = poses[:, 2] + self._yaw
        dx, dy = np.cos(heading), np.sin(heading)
        nearest = self.world.ray_distances(ox, oy, dx, dy, MAX_DISTANCE)
        if scene is not None and robots_xy is not None and len(robots_xy) > 1:
            bodies = scene.robot_hits(ox[:, None], oy[:, None], dx[:, None], dy[:, None], np.asarray(robots_xy),
                                      np.arange(len(poses)) if own is None else np.asarray(own), reach=self.reach)
            nearest = np.minimum(nearest, np.where(bodies[:, 0] <= MAX_DISTANCE, bodies[:, 0], np.inf))
        return nearest

    def read(self, poses: np.ndarray, rng: np.random.Generator | None, scene: Scene | None = None,
             robots_xy: np.ndarray | None = None, own: np.ndarray | None = None) -> np.ndarray:
        """Values (R,) as Webots' getValue() returns them (inf, nothing hit, reads the last row: 2000)."""
        distance = self.distances(poses, scene, robots_xy, own)
        return lookup(np.minimum(distance, MAX_DISTANCE), TOF_LOOKUP_TABLE, rng)
