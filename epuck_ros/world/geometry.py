"""The world's walls and obstacles prepared once for queries: float tuples for one disc, NumPy arrays for many.

The primitives every query is built of live here: signed distances and normals from points to the surfaces,
and distances along rays to edges and circles. The ray casting (`raycast`) and the collision rules
(`collisions`) combine them; the grid and clearance map that keep the cost per robot flat are in `cells`.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from epuck_ros.world.cells import ClearanceMap, ObstacleGrid
from epuck_ros.world.obstacles import Box, Cylinder

CONTACT_TOLERANCE = 1e-6
"""m; a disc this close to an obstacle touches it (a pushed-out disc sits at exactly its radius)."""


class Geometry:
    """A World's walls and obstacles prepared once: float tuples for one disc, NumPy arrays for many.

    A one-disc query is one point against a few obstacles, where NumPy's per-call overhead would cost more
    than the arithmetic: plain floats, with a bounding-circle test that skips every obstacle out of reach.
    Rays and many discs go to NumPy, each against the obstacles a grid lists near it. The obstacle arrays end
    with one dummy obstacle far away, which pads the grid's rows.
    """

    def __init__(self, arena_size: tuple[float, float], boxes: Sequence[Box], cylinders: Sequence[Cylinder]) -> None:
        self.half_x, self.half_y = arena_size[0] / 2.0, arena_size[1] / 2.0
        self.boxes = [(b.x, b.y, math.cos(b.yaw), math.sin(b.yaw), b.size_x / 2, b.size_y / 2,
                       math.hypot(b.size_x, b.size_y) / 2) for b in boxes]
        self.cylinders = [(c.x, c.y, c.radius) for c in cylinders]
        self.box_count, self.cylinder_count = len(self.boxes), len(self.cylinders)
        far = 1e9
        (self.box_x, self.box_y, self.box_cos, self.box_sin, self.box_half_x, self.box_half_y,
         self.box_bound) = np.array(self.boxes + [(far, far, 1.0, 0.0, 1.0, 1.0, 1.0)]).T.copy()
        self.cyl_x, self.cyl_y, self.cyl_radius = np.array(self.cylinders + [(far, far, 1.0)]).T.copy()
        # Edges as segments (start, start-to-end vector) for rays: the 4 walls, 4 per box, a far dummy edge.
        hx, hy = self.half_x, self.half_y
        corners = [[(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)]] + [box.corners() for box in boxes]
        starts = [corner for box in corners for corner in box] + [(far, far)]
        ends = [corner for box in corners for corner in box[1:] + box[:1]] + [(far + 1.0, far)]
        self.edge_start_x, self.edge_start_y = np.array(starts).T.copy()
        self.edge_x, self.edge_y = (np.array(ends) - np.array(starts)).T.copy()
        self.edge_total = len(starts) - 1
        # Per surface index (surfaces_within's), its edges (start x, y, vector x, y) and its circle, as floats
        # taken from the arrays above (cast_near). Edge k runs from corner k: the walls at -x, -y, +x, +y are
        # edges 1, 2, 3, 0.
        edges = list(zip(*(a.tolist() for a in (self.edge_start_x, self.edge_start_y, self.edge_x, self.edge_y))))
        self.surface_edges = ([[edges[k]] for k in (1, 2, 3, 0)]
                              + [edges[4 + 4 * b:8 + 4 * b] for b in range(self.box_count)]
                              + [[]] * self.cylinder_count)
        self.surface_circles = [None] * (4 + self.box_count) + list(zip(*(a[:-1].tolist() for a in (
            self.cyl_x, self.cyl_y, self.cyl_radius))))
        self._shaped: dict[tuple[str, int], tuple[np.ndarray, ...]] = {}   # see _all_edges
        self._grids: dict[float, ObstacleGrid] = {}
        self._clearance: ClearanceMap | None = None

    def clearance(self) -> ClearanceMap:
        """The clearance map (built on first use, then kept)."""
        if self._clearance is None:
            self._clearance = ClearanceMap(self)
        return self._clearance

    def grid(self, reach: float) -> ObstacleGrid:
        """The obstacle grid for queries that reach `reach` from a point (built on first use, then kept)."""
        if reach not in self._grids:
            self._grids[reach] = ObstacleGrid(self, reach)
        return self._grids[reach]

    def surfaces(self, x: np.ndarray, y: np.ndarray, box_ids: np.ndarray,
                 cylinder_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signed distance and outward normal (each (K, 4 + B + C)) from points (K, 1) to the four walls, the boxes
        `box_ids` (K, B) and the cylinders `cylinder_ids` (K, C): `surfaces_within` for many points at once."""
        walls = np.concatenate([x + self.half_x, y + self.half_y, self.half_x - x, self.half_y - y], axis=1)
        wall_x = np.broadcast_to(np.array([1.0, 0.0, -1.0, 0.0]), walls.shape)
        wall_y = np.broadcast_to(np.array([0.0, 1.0, 0.0, -1.0]), walls.shape)
        cos, sin = self.box_cos[box_ids], self.box_sin[box_ids]
        dx, dy = x - self.box_x[box_ids], y - self.box_y[box_ids]
        local_x, local_y = dx * cos + dy * sin, dy * cos - dx * sin
        gap_x, gap_y = np.abs(local_x) - self.box_half_x[box_ids], np.abs(local_y) - self.box_half_y[box_ids]
        sign_x, sign_y = np.copysign(1.0, local_x), np.copysign(1.0, local_y)
        inside, through_x = (gap_x <= 0.0) & (gap_y <= 0.0), gap_x > gap_y
        out_x, out_y = np.maximum(gap_x, 0.0), np.maximum(gap_y, 0.0)
        outside = np.hypot(out_x, out_y)
        with np.errstate(invalid='ignore', divide='ignore'):   # 0/0 inside a box, where the other branch is taken
            local_nx = np.where(inside, np.where(through_x, sign_x, 0.0), sign_x * out_x / outside)
            local_ny = np.where(inside, np.where(through_x, 0.0, sign_y), sign_y * out_y / outside)
        box = np.where(inside, np.where(through_x, gap_x, gap_y), outside)
        dx, dy = x - self.cyl_x[cylinder_ids], y - self.cyl_y[cylinder_ids]
        centre = np.hypot(dx, dy)
        away = centre > 0.0
        safe = np.where(away, centre, 1.0)
        return (np.concatenate([walls, box, centre - self.cyl_radius[cylinder_ids]], axis=1),
                np.concatenate([wall_x, local_nx * cos - local_ny * sin, np.where(away, dx / safe, 1.0)], axis=1),
                np.concatenate([wall_y, local_nx * sin + local_ny * cos, np.where(away, dy / safe, 0.0)], axis=1))

    def rays_to_edges(self, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray,
                      ids: np.ndarray | None = None) -> np.ndarray:
        """Distance (E, *rays) along rays (origins, directions: arrays of one shape) to the edges `ids` (E, ...),
        which broadcast against the rays, or to every edge (None); inf where the ray misses. A ray parallel to an
        edge divides by zero: call under np.errstate(divide='ignore', invalid='ignore') (its NaN or inf misses)."""
        start_x, start_y, edge_x, edge_y = (self._all_edges(np.ndim(ox)) if ids is None else
                                            (self.edge_start_x[ids], self.edge_start_y[ids], self.edge_x[ids],
                                             self.edge_y[ids]))
        to_x, to_y = start_x - ox, start_y - oy
        inverse = 1.0 / (dir_x * edge_y - dir_y * edge_x)
        along_ray = (to_x * edge_y - to_y * edge_x) * inverse
        along_edge = (to_x * dir_y - to_y * dir_x) * inverse
        # A hit: along_ray >= 0 and 0 <= along_edge <= 1; 1 - along_edge has the sign of the exact difference, and
        # NaN (parallel) fails, so this is that test in fewer NumPy calls.
        return np.where(np.minimum(np.minimum(along_ray, along_edge), 1.0 - along_edge) >= 0.0, along_ray, np.inf)

    def rays_to_cylinders(self, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray,
                          ids: np.ndarray | None = None) -> np.ndarray:
        """Distance (C, *rays) along rays to the cylinders `ids` (as for rays_to_edges); inf where the ray misses."""
        if ids is None:
            return ray_circle(ox, oy, dir_x, dir_y, *self._all_cylinders(np.ndim(ox)))
        return ray_circle(ox, oy, dir_x, dir_y, self.cyl_x[ids], self.cyl_y[ids], self.cyl_radius[ids])

    def _all_edges(self, ndim: int) -> tuple[np.ndarray, ...]:
        """Every edge's start and vector, shaped (E, 1 x ndim) to broadcast against rays of `ndim` dimensions."""
        if ('edges', ndim) not in self._shaped:
            shape = (self.edge_total,) + (1,) * ndim
            self._shaped['edges', ndim] = tuple(a[:self.edge_total].reshape(shape) for a in (
                self.edge_start_x, self.edge_start_y, self.edge_x, self.edge_y))
        return self._shaped['edges', ndim]

    def _all_cylinders(self, ndim: int) -> tuple[np.ndarray, ...]:
        """Every cylinder's centre and radius, shaped as _all_edges."""
        if ('cylinders', ndim) not in self._shaped:
            shape = (self.cylinder_count,) + (1,) * ndim
            self._shaped['cylinders', ndim] = tuple(a[:self.cylinder_count].reshape(shape) for a in (
                self.cyl_x, self.cyl_y, self.cyl_radius))
        return self._shaped['cylinders', ndim]

    def surfaces_near(self, x: float, y: float, distance: float) -> list[int]:
        """Indexes of the surfaces closer than `distance` to (x, y) (for `raycast.cast_near`); empty when none is."""
        return [index for index, *_ in self.surfaces_within(x, y, distance)]

    def maybe_within(self, x: np.ndarray, y: np.ndarray, reach: float) -> np.ndarray:
        """(N,) for points (x, y: (N,)), False where `surfaces_within` surely finds nothing within `reach`: the
        walls' tests and the obstacles' bounding circles, CONTACT_TOLERANCE wider (NumPy's rounding need not be the
        one-point code's). A point marked True may still have nothing within reach: ask `surfaces_within`."""
        reach = reach + CONTACT_TOLERANCE
        near = (x + self.half_x < reach) | (y + self.half_y < reach) | (self.half_x - x < reach) | \
            (self.half_y - y < reach)
        if self.box_count:
            dx, dy = x[:, None] - self.box_x[:-1], y[:, None] - self.box_y[:-1]
            near |= (dx * dx + dy * dy < (self.box_bound[:-1] + reach) ** 2).any(axis=1)
        if self.cylinder_count:
            dx, dy = x[:, None] - self.cyl_x[:-1], y[:, None] - self.cyl_y[:-1]
            near |= (np.hypot(dx, dy) - self.cyl_radius[:-1] < reach).any(axis=1)
        return near

    def surfaces_within(self, x: float, y: float, reach: float) -> list[tuple[int, float, float, float]]:
        """(index, signed distance, normal x, normal y) of each surface closer than `reach` to the point (x, y).

        Indexes run over the walls at -x, -y, +x, +y, then the boxes, then the cylinders. The normal points from
        the surface towards the point; the distance is negative inside an obstacle (the normal then points to
        the nearest way out), so a push of (radius - distance) along the normal frees a disc from that surface.
        """
        found = []   # the walls one by one: cheaper than a loop over them
        if x + self.half_x < reach:
            found.append((0, x + self.half_x, 1.0, 0.0))
        if y + self.half_y < reach:
            found.append((1, y + self.half_y, 0.0, 1.0))
        if self.half_x - x < reach:
            found.append((2, self.half_x - x, -1.0, 0.0))
        if self.half_y - y < reach:
            found.append((3, self.half_y - y, 0.0, -1.0))
        for index, (bx, by, cos, sin, half_x, half_y, bound) in enumerate(self.boxes, start=4):
            dx, dy = x - bx, y - by
            if dx * dx + dy * dy < (bound + reach) ** 2:
                distance, local_nx, local_ny = box_distance(dx * cos + dy * sin, dy * cos - dx * sin, half_x, half_y)
                if distance < reach:
                    found.append((index, distance, local_nx * cos - local_ny * sin, local_nx * sin + local_ny * cos))
        for index, (cx, cy, radius) in enumerate(self.cylinders, start=4 + len(self.boxes)):
            dx, dy = x - cx, y - cy
            centre_distance = math.hypot(dx, dy)
            if centre_distance - radius < reach:
                nx, ny = (dx / centre_distance, dy / centre_distance) if centre_distance > 0.0 else (1.0, 0.0)
                found.append((index, centre_distance - radius, nx, ny))
        return found


def box_distance(local_x: float, local_y: float, half_x: float, half_y: float) -> tuple[float, float, float]:
    """Signed distance from a point (in the box frame) to an axis-aligned box, and the unit normal there."""
    gap_x = abs(local_x) - half_x
    gap_y = abs(local_y) - half_y
    sign_x, sign_y = math.copysign(1.0, local_x), math.copysign(1.0, local_y)
    if gap_x <= 0.0 and gap_y <= 0.0:  # inside: out through the nearest face
        return (gap_x, sign_x, 0.0) if gap_x > gap_y else (gap_y, 0.0, sign_y)
    out_x, out_y = max(gap_x, 0.0), max(gap_y, 0.0)
    distance = math.hypot(out_x, out_y)
    return distance, sign_x * out_x / distance, sign_y * out_y / distance


def ray_circle(ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray, centre_x: np.ndarray,
               centre_y: np.ndarray, radius: np.ndarray | float) -> np.ndarray:
    """Distance along each ray (origin, unit direction) to a circle, broadcast; inf where it misses.

    Only the near crossing counts, and only ahead of the origin: a ray starting inside the circle sees nothing.
    """
    from_x, from_y = ox - centre_x, oy - centre_y
    half_b = from_x * dir_x + from_y * dir_y
    discriminant = half_b * half_b - (from_x * from_x + from_y * from_y - radius * radius)
    root = -half_b - np.sqrt(np.maximum(discriminant, 0.0))
    return np.where(np.minimum(discriminant, root) < 0.0, np.inf, root)   # a miss: either is negative
