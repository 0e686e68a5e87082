"""The world as the senses see it: walls and obstacles with colour and height, a painted floor, other robots.

Built once from a World and its Appearance. Walls and box edges are segments, cylinders and robots circles; a
ray query returns the distance to every one of them (objects on the leading axis, NumPy over every ray), so a
sensor picks the nearest (the camera) or asks whether anything tall enough stands in the way (light occlusion).
The floor is painted once into a texture (`FLOOR_RESOLUTION` per texel, at most `MAX_TEXELS` a side), which the
camera and the ground sensors sample by index: constant cost whatever the paint.
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.world.appearance import ROBOT_COLOR, Appearance, Paint
from epuck_ros.model import BODY_TOP, RobotModel
from epuck_ros.spatial import close_pairs
from epuck_ros.world import World

FLOOR_RESOLUTION = 0.002
"""m per floor texel: a 1 m arena is 500 x 500 texels; a 2 cm line is 10 texels wide."""
MAX_TEXELS = 2048
"""Texels per side at most: a huge arena gets coarser texels rather than a huge texture."""
ROBOT_VIEW_RANGE = 1.0
"""m; other robots farther than this are not drawn by the camera nor block light (cost bounded in swarms)."""


class Scene:
    """Static segments and circles with colour and height, the floor texture, and the robots' bodies."""

    def __init__(self, world: World, appearance: Appearance = Appearance(), model: RobotModel = RobotModel()) -> None:
        self.world, self.appearance, self.model = world, appearance, model
        hx, hy = world.arena_size[0] / 2.0, world.arena_size[1] / 2.0
        corners = [[(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)]]
        colors = [appearance.wall_color] * 4
        heights = [appearance.wall_height] * 4
        for index, box in enumerate(world.boxes):
            corners.append(_box_corners(box.x, box.y, box.size_x, box.size_y, box.yaw))
            colors += [appearance.box_color(index)] * 4
            heights += [appearance.box_height(index)] * 4
        start = np.array([c for shape in corners for c in shape])
        end = np.array([c for shape in corners for c in shape[1:] + shape[:1]])
        circles = [(c.x, c.y, c.radius) for c in world.cylinders]
        colors += [appearance.cylinder_color(i) for i in range(len(circles))]
        heights += [appearance.cylinder_height(i) for i in range(len(circles))]
        self.segment_count = len(start)
        self._ax, self._ay = (start[:, k].reshape(-1, 1, 1).copy() for k in (0, 1))
        self._ex, self._ey = ((end - start)[:, k].reshape(-1, 1, 1).copy() for k in (0, 1))
        circle_array = np.array(circles, dtype=float).reshape(-1, 3)
        self._cx, self._cy = (circle_array[:, k].reshape(-1, 1, 1).copy() for k in (0, 1))
        self._cr2 = (circle_array[:, 2] ** 2).reshape(-1, 1, 1)
        self.colors = np.array(colors + [ROBOT_COLOR], dtype=float)
        """(objects + 1, 3): each object's colour; the last row is a robot's."""
        self.heights = np.array(heights + [BODY_TOP], dtype=float)
        self.robot_index = len(colors)
        self.floor = FloorTexture(world.arena_size, appearance.floor_color, appearance.paint)

    def hits(self, ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        """Distance (objects, R, K) along rays from (ox, oy) (R, 1) with unit directions (dx, dy) (R, K) to each
        static object (segments, then circles); inf where a ray misses it or meets it behind its origin."""
        with np.errstate(divide='ignore', invalid='ignore'):
            rx, ry = self._ax - ox, self._ay - oy
            denominator = dx * self._ey - dy * self._ex
            t = (rx * self._ey - ry * self._ex) / denominator
            u = (rx * dy - ry * dx) / denominator
            segments = np.where((t > 0.0) & (u >= 0.0) & (u <= 1.0), t, np.inf)
            if not len(self._cr2):
                return segments
            circles = _circle_hits(self._cx - ox, self._cy - oy, self._cr2, dx, dy)
        return np.concatenate([segments, circles])

    def robot_hits(self, ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                   robots_xy: np.ndarray, own: np.ndarray, view: tuple[np.ndarray, float] | None = None) -> np.ndarray:
        """Distance (R, K) along each viewer's rays (origins (R, 1) or (R, K), directions (R, K)) to the nearest
        other robot body within ROBOT_VIEW_RANGE; `own` (R,) is each viewer's own row in `robots_xy` (N, 2).
        `view` (a camera's headings and half field of view, origins (R, 1)) leaves out the bodies it cannot see."""
        nearest = np.full(dx.shape, np.inf)
        if len(robots_xy) < 2:
            return nearest
        first, second = close_pairs(robots_xy, ROBOT_VIEW_RANGE)
        viewer_of = np.full(len(robots_xy), -1)
        viewer_of[own] = np.arange(len(own))
        viewers = np.concatenate([viewer_of[first], viewer_of[second]])
        targets = np.concatenate([second, first])
        keep = viewers >= 0
        viewers, targets = viewers[keep], targets[keep]
        if view is not None:   # a camera: only the bodies within its field of view (headings (R,), half-angle)
            heading, half_angle = view
            rx, ry = robots_xy[targets, 0] - ox[viewers, 0], robots_xy[targets, 1] - oy[viewers, 0]
            cos, sin = np.cos(heading[viewers]), np.sin(heading[viewers])
            ahead, aside = rx * cos + ry * sin, ry * cos - rx * sin
            radius = self.model.body_radius
            seen = (ahead > -radius) & (np.abs(aside) - radius / math.cos(half_angle) < ahead * math.tan(half_angle))
            viewers, targets = viewers[seen], targets[seen]
        if not len(viewers):
            return nearest
        order = np.argsort(viewers, kind='stable')
        viewers, targets = viewers[order], targets[order]
        radius2 = self.model.body_radius ** 2
        with np.errstate(invalid='ignore'):
            t = _circle_hits(robots_xy[targets, 0:1] - ox[viewers], robots_xy[targets, 1:2] - oy[viewers], radius2,
                             dx[viewers], dy[viewers])
        starts = np.flatnonzero(np.r_[True, viewers[1:] != viewers[:-1]])
        nearest[viewers[starts]] = np.minimum.reduceat(t, starts, axis=0)
        return nearest


def _circle_hits(fx: np.ndarray, fy: np.ndarray, r2: np.ndarray | float, dx: np.ndarray,
                 dy: np.ndarray) -> np.ndarray:
    """Distance along unit rays to the near side of circles at offset (fx, fy) from the origin; inf on a miss or
    behind (a ray starting inside a circle does not see it: a sensor inside its own body)."""
    b = fx * dx + fy * dy
    c = fx * fx + fy * fy - r2
    t = b - np.sqrt(b * b - c)
    return np.where((c > 0.0) & (t > 0.0), t, np.inf)


def _box_corners(x: float, y: float, size_x: float, size_y: float, yaw: float) -> list[tuple[float, float]]:
    cos, sin = math.cos(yaw), math.sin(yaw)
    hx, hy = size_x / 2.0, size_y / 2.0
    corners = ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))
    return [(x + cos * lx - sin * ly, y + sin * lx + cos * ly) for lx, ly in corners]


class FloorTexture:
    """The arena's floor as an RGB image (float 0..1), texel (row j, column i) centred at
    (-half_x + (i + 0.5) * step, -half_y + (j + 0.5) * step); points off the floor take the nearest edge texel."""

    def __init__(self, arena_size: tuple[float, float], color: tuple[float, float, float],
                 paint: tuple[Paint, ...]) -> None:
        self.step = max(FLOOR_RESOLUTION, max(arena_size) / MAX_TEXELS)
        self.half_x, self.half_y = arena_size[0] / 2.0, arena_size[1] / 2.0
        self.columns = max(1, math.ceil(arena_size[0] / self.step))
        self.rows = max(1, math.ceil(arena_size[1] / self.step))
        self.image = np.empty((self.rows, self.columns, 3))
        self.image[:] = color
        self.plain = not paint
        for item in paint:
            self._paint(item)
        self.red = self.image[:, :, 0].ravel().copy()
        """The red channel, flat: what an infra-red ground sensor sees."""
        self.flat = self.image.reshape(-1, 3)

    def index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat texel index of each point (any shape)."""
        i = np.minimum(np.maximum(((x + self.half_x) / self.step).astype(np.int64), 0), self.columns - 1)
        j = np.minimum(np.maximum(((y + self.half_y) / self.step).astype(np.int64), 0), self.rows - 1)
        return j * self.columns + i   # (np.clip costs more on a few points: it looks up the type's limits)

    def texel(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat texel index of points on the floor (any shape), as `index` for points within it; points off the
        floor get some valid index (the camera asks only for floor its walls hide there)."""
        i = ((x + self.half_x) * (1.0 / self.step)).astype(np.int32)
        j = ((y + self.half_y) * (1.0 / self.step)).astype(np.int32)
        flat = j * self.columns + i
        return np.minimum(np.maximum(flat, 0, out=flat), self.columns * self.rows - 1, out=flat)

    def _grid(self, x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice, np.ndarray, np.ndarray] | None:
        """Texel rows and columns whose centres may lie within the box, and those centres' coordinates."""
        i0 = max(0, int(math.floor((x0 + self.half_x) / self.step)))
        i1 = min(self.columns, int(math.ceil((x1 + self.half_x) / self.step)) + 1)
        j0 = max(0, int(math.floor((y0 + self.half_y) / self.step)))
        j1 = min(self.rows, int(math.ceil((y1 + self.half_y) / self.step)) + 1)
        if i0 >= i1 or j0 >= j1:
            return None
        xs = -self.half_x + (np.arange(i0, i1) + 0.5) * self.step
        ys = -self.half_y + (np.arange(j0, j1) + 0.5) * self.step
        return slice(j0, j1), slice(i0, i1), xs[None, :], ys[:, None]

    def _paint(self, item: Paint) -> None:
        points = np.array(item.points, dtype=float)
        reach = item.radius if item.kind == 'disc' else item.width / 2.0
        grid = self._grid(points[:, 0].min() - reach, points[:, 1].min() - reach,
                          points[:, 0].max() + reach, points[:, 1].max() + reach)
        if grid is None:
            return
        rows, columns, xs, ys = grid
        if item.kind == 'disc':
            inside = (xs - points[0, 0]) ** 2 + (ys - points[0, 1]) ** 2 <= item.radius ** 2
        elif item.kind == 'polygon':
            inside = np.zeros((len(ys), xs.shape[1]), dtype=bool)
            for (ax, ay), (bx, by) in zip(points, np.roll(points, -1, axis=0)):   # even-odd rule
                if ay == by:
                    continue
                crosses = (ay > ys) != (by > ys)
                at_x = ax + (ys - ay) * (bx - ax) / (by - ay)
                inside ^= crosses & (xs < at_x)
        else:
            inside = np.zeros((len(ys), xs.shape[1]), dtype=bool)
            for (ax, ay), (bx, by) in zip(points[:-1], points[1:]):
                ex, ey = bx - ax, by - ay
                length2 = ex * ex + ey * ey
                along = np.clip(((xs - ax) * ex + (ys - ay) * ey) / length2, 0.0, 1.0) if length2 else 0.0
                inside |= (xs - ax - along * ex) ** 2 + (ys - ay - along * ey) ** 2 <= reach ** 2
        self.image[rows, columns][inside] = item.color
