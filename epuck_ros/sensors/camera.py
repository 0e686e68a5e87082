"""The e-puck's camera: a 2.5-D renderer, one ray per image column over the 2-D world.

Each column's ray finds the nearest wall, obstacle or other robot; that object's distance and height give the
rows it covers (perspective: a thing at depth z and height h spans elevations -cam_z/z .. (h - cam_z)/z). Rows
below it that look down meet the floor, whose point is found by perspective and read from the floor texture;
rows above it see the sky. NumPy across robots and columns at once. What it leaves out: what stands behind a
thing lower than the camera (its column shows the sky above it), shading, the robot's own body.

Geometry (pinhole, square pixels, Webots' convention): focal length f = (width / 2) / tan(fov / 2) pixels;
column c looks at atan((width / 2 - (c + 0.5)) / f) left of the axis, row r at elevation
((height / 2 - (r + 0.5)) / f) in tangent units. Column 0 is the image's left (the robot's left).
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.world.appearance import SKY_COLOR
from epuck_ros.model import CAMERA_FOV, CAMERA_HEIGHT, CAMERA_NEAR, CAMERA_POSE, CAMERA_WIDTH
from epuck_ros.sensors.scene import Scene


class Camera:
    """Renders (R, height, width, 3) uint8 RGB images for robots at given poses."""

    def __init__(self, scene: Scene, width: int = CAMERA_WIDTH, height: int = CAMERA_HEIGHT,
                 fov: float = CAMERA_FOV) -> None:
        if width < 1 or height < 1 or not 0.0 < fov < math.pi:
            raise ValueError(f'camera: width and height must be positive and 0 < fov < pi, got {width}, {height}, '
                             f'{fov}')
        self.scene, self.width, self.height, self.fov = scene, int(width), int(height), float(fov)
        self.focal = (self.width / 2.0) / math.tan(self.fov / 2.0)
        tangents = (self.width / 2.0 - (np.arange(self.width) + 0.5)) / self.focal
        self.column_angles = np.arctan(tangents)
        self._column_cos = np.cos(self.column_angles)
        self._elevation = (self.height / 2.0 - (np.arange(self.height) + 0.5)) / self.focal   # tan, per row
        below = np.flatnonzero(self._elevation < 0.0)
        self._below = slice(int(below[0]), self.height) if len(below) else slice(self.height, self.height)
        self._rows = np.arange(self.height, dtype=float)[:, None]                       # (V, 1)
        self._middle = self.height / 2.0 - 0.5
        # How far along each floor-looking pixel's ray the floor is (fixed by the mounting): (V', C).
        self._reach = CAMERA_POSE[2] / -self._elevation[self._below, None] / self._column_cos[None, :]
        # One palette for every pixel: the objects' colours, the sky, then every floor texel; a pixel is an index.
        objects = len(scene.colors)
        self._floor_offset = objects + 1
        self._palette = np.round(np.concatenate([scene.colors, [SKY_COLOR], scene.floor.flat]) * 255.0).astype(np.uint8)
        self._background = np.full((self.height, self.width), objects, dtype=np.int32)   # the sky ...
        self._background[self._below] = self._floor_offset                              # ... and a plain floor
        self._mount_x, self._mount_y, self._mount_z = CAMERA_POSE
        self._top = (scene.heights - self._mount_z) * self.focal     # per object: f (h - cam_z)
        self._bottom = self._mount_z * self.focal

    @property
    def vertical_fov(self) -> float:
        return 2.0 * math.atan(self.height / 2.0 / self.focal)

    def render(self, poses: np.ndarray, robots_xy: np.ndarray | None = None,
               own: np.ndarray | None = None) -> np.ndarray:
        """Images (R, height, width, 3) uint8 for robots at `poses` (R, 3); `robots_xy` (N, 2): every robot's
        centre (drawn as bodies), `own` (R,): each viewer's row in it."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        x, y, yaw = poses[:, 0:1], poses[:, 1:2], poses[:, 2:3]
        cos, sin = np.cos(yaw), np.sin(yaw)
        ox = x + cos * self._mount_x - sin * self._mount_y
        oy = y + sin * self._mount_x + cos * self._mount_y
        angles = yaw + self.column_angles
        dx, dy = np.cos(angles), np.sin(angles)
        hits = self.scene.hits(ox, oy, dx, dy)
        nearest = hits.argmin(axis=0)                                      # (R, C)
        distance = hits.min(axis=0)
        if robots_xy is not None and len(robots_xy) > 1:
            robots = self.scene.robot_hits(ox, oy, dx, dy, np.asarray(robots_xy, dtype=float),
                                           np.arange(len(poses)) if own is None else np.asarray(own),
                                           (poses[:, 2], self.fov / 2.0))
            closer = robots < distance
            nearest[closer] = self.scene.robot_index
            distance = np.where(closer, robots, distance)
        depth = distance * self._column_cos                               # (R, C), along the optical axis
        # Rows covered by the nearest object: those whose elevation lies between its foot and its top.
        first_row = (self._middle - self._top[nearest] / depth)[:, None, :]
        last_row = np.where(depth >= CAMERA_NEAR, self._middle + self._bottom / depth, -1.0)[:, None, :]
        covered = (self._rows >= first_row) & (self._rows <= last_row)          # (R, V, C)
        if self.scene.floor.plain:
            pixels = self._background
        else:
            pixels = np.broadcast_to(self._background, covered.shape).copy()
            reach = self._reach[None]
            pixels[:, self._below] += self.scene.floor.texel(ox[:, :, None] + dx[:, None, :] * reach,
                                                             oy[:, :, None] + dy[:, None, :] * reach)
        return self._palette[np.where(covered, nearest[:, None, :].astype(np.int32), pixels)]


def camera_matrix(width: int, height: int, fov: float) -> list[float]:
    """The intrinsic matrix K (row-major 3 x 3) of this camera model in ROS's convention (pixel centres at whole
    numbers): the focal length in pixels, the principal point in the image's middle."""
    focal = (width / 2.0) / math.tan(fov / 2.0)
    return [focal, 0.0, width / 2.0 - 0.5, 0.0, focal, height / 2.0 - 0.5, 0.0, 0.0, 1.0]
