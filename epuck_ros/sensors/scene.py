"""The world as the senses see it: walls and obstacles with colour and height, a painted floor, other robots.

Built once from a World and its Appearance. Walls and box edges are segments, cylinders and robots circles; a
ray query returns the distance to every one of them (objects on the leading axis, NumPy over every ray), so a
sensor picks the nearest (the camera) or asks whether anything tall enough stands in the way (light occlusion).
The floor is painted once into a texture (`FLOOR_RESOLUTION` per texel, at most `MAX_TEXELS` a side), which the
camera and the ground sensors sample by index: constant cost whatever the paint. Painting costs each segment and disc
its own bounding box, a polygon its bounding box and a look per edge and row (`appearance.paint_work`, which the
world loader bounds).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np

from epuck_ros.world.appearance import MAX_TEXELS, ROBOT_COLOR, Appearance, Paint, floor_step, texel_span
from epuck_ros.model import BODY_TOP, RobotModel
from epuck_ros.spatial import close_pairs
from epuck_ros.world import World

CROSSINGS_AT_ONCE = 1 << 20
"""Edge-row crossings of a polygon worked on at once: bounds painting's memory whatever the polygon."""
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
                   robots_xy: np.ndarray, own: np.ndarray, view: tuple[np.ndarray, float] | None = None,
                   reach: float = ROBOT_VIEW_RANGE) -> np.ndarray:
        """Distance (R, K) along each viewer's rays (origins (R, 1) or (R, K), directions (R, K)) to the nearest
        other robot body whose centre is within `reach` of the viewer's; `own` (R,) is each viewer's own row in
        `robots_xy` (N, 2).
        `view` (a camera's headings and half field of view, origins (R, 1)) leaves out the bodies it cannot see."""
        nearest = np.full(dx.shape, np.inf)
        if len(robots_xy) < 2:
            return nearest
        first, second = close_pairs(robots_xy, reach)
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
    (-half_x + (i + 0.5) * step, -half_y + (j + 0.5) * step); points off the floor take the nearest edge texel.
    `max_texels`: texels per side at most (a picture needs fewer than the senses)."""

    def __init__(self, arena_size: tuple[float, float], color: tuple[float, float, float],
                 paint: tuple[Paint, ...], max_texels: int = MAX_TEXELS) -> None:
        self.step = floor_step(arena_size, max_texels)
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
        i0, i1 = texel_span(x0, x1, self.half_x, self.step, self.columns)
        j0, j1 = texel_span(y0, y1, self.half_y, self.step, self.rows)
        if i0 >= i1 or j0 >= j1:
            return None
        xs = -self.half_x + (np.arange(i0, i1) + 0.5) * self.step
        ys = -self.half_y + (np.arange(j0, j1) + 0.5) * self.step
        return slice(j0, j1), slice(i0, i1), xs[None, :], ys[:, None]

    def _fill(self, x0: float, y0: float, x1: float, y1: float, inside: Callable, color: tuple) -> None:
        """Paint the texels of the box [x0, x1] x [y0, y1] where `inside(xs (1, I), ys (J, 1))` holds."""
        grid = self._grid(x0, y0, x1, y1)
        if grid is not None:
            rows, columns, xs, ys = grid
            self.image[rows, columns][inside(xs, ys)] = color

    def _paint(self, item: Paint) -> None:
        points = np.array(item.points, dtype=float)
        if item.kind == 'disc':
            (cx, cy), radius = points[0], item.radius
            self._fill(cx - radius, cy - radius, cx + radius, cy + radius,
                       lambda xs, ys: (xs - cx) ** 2 + (ys - cy) ** 2 <= radius ** 2, item.color)
        elif item.kind == 'polygon':
            self._polygon(points, item.color)
        else:
            reach = item.width / 2.0
            for (ax, ay), (bx, by) in zip(points[:-1].tolist(), points[1:].tolist()):   # each its own box
                self._fill(min(ax, bx) - reach, min(ay, by) - reach, max(ax, bx) + reach, max(ay, by) + reach,
                           partial(_near_segment, ax, ay, bx - ax, by - ay, reach), item.color)

    def _polygon(self, points: np.ndarray, color: tuple) -> None:
        """Even-odd rule, row by row: a texel is inside when an odd number of edges cross its row to its right.
        Each edge is looked at only on the rows it spans; the texels of a row then count the crossings beyond
        them (a suffix sum), so the cost is the crossings plus the bounding box, not edges times the box."""
        grid = self._grid(*points.min(axis=0), *points.max(axis=0))
        if grid is None:
            return
        rows, columns, xs, ys = grid
        xs, ys = xs[0], ys[:, 0]
        ax, ay = points[:, 0], points[:, 1]
        bx, by = np.roll(ax, -1), np.roll(ay, -1)
        first = np.searchsorted(ys, np.minimum(ay, by), side='left')   # rows with min <= y < max: crossed
        last = np.searchsorted(ys, np.maximum(ay, by), side='left')
        counts = np.zeros((len(ys), len(xs) + 1), dtype=np.int64)   # crossings with k texel centres left of them
        spans = last - first
        edges = np.flatnonzero(spans > 0)
        per_chunk = max(1, CROSSINGS_AT_ONCE // len(ys))   # an edge spans len(ys) rows at most
        for start in range(0, len(edges), per_chunk):
            chosen = edges[start:start + per_chunk]
            lengths = spans[chosen]
            edge = np.repeat(chosen, lengths)
            row = first[edge] + np.arange(len(edge)) - np.repeat(np.cumsum(lengths) - lengths, lengths)
            at_x = ax[edge] + (ys[row] - ay[edge]) * (bx[edge] - ax[edge]) / (by[edge] - ay[edge])
            np.add.at(counts, (row, np.searchsorted(xs, at_x, side='left')), 1)
        beyond = np.cumsum(counts[:, ::-1], axis=1)[:, ::-1]   # beyond[j, k]: crossings with at least k centres left
        self.image[rows, columns][beyond[:, 1:] % 2 == 1] = color


def _near_segment(ax: float, ay: float, ex: float, ey: float, reach: float, xs: np.ndarray,
                  ys: np.ndarray) -> np.ndarray:
    """Whether texel centres lie within `reach` of the segment from (ax, ay) along (ex, ey)."""
    length2 = ex * ex + ey * ey
    along = np.clip(((xs - ax) * ex + (ys - ay) * ey) / length2, 0.0, 1.0) if length2 else 0.0
    return (xs - ax - along * ex) ** 2 + (ys - ay - along * ey) ** 2 <= reach ** 2
