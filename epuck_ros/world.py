"""The world the e-puck drives in: a walled rectangular arena with boxes and cylinders, read from YAML.

The arena is Webots' RectangleArena: the floor is centred on the origin and its walls stand outside the floor,
so the free area is exactly `arena_size`. Geometry is 2-D (everything is taller than the IR rays). A World
prepares its obstacles once: plain floats for one disc (one robot), NumPy arrays for many rays and discs, with
a grid of cells listing the obstacles near each cell and a clearance map saying which points are near anything
(see `_Geometry` for why), so the cost per robot does not grow with the number of obstacles.

World file. Every section is optional (none at all: an empty 1 m x 1 m arena, one robot `epuck` at the origin
facing +x); a box needs position and size (yaw defaults to 0), a cylinder position and radius, a robot a start:

    arena: {size: [1.0, 1.0]}
    boxes: [{position: [x, y], size: [sx, sy], yaw: 0.0}]
    cylinders: [{position: [x, y], radius: r}]
    robots: [{name: epuck0, start: [x, y, yaw]}, {name: epuck1, start: [x, y, yaw]}]
    robot: {start: [x, y, yaw]}      # the one-robot form (named `epuck`); not together with `robots`

The file is untrusted input: it is read only if it is a regular file under MAX_FILE_BYTES, YAML aliases and deep
nesting are refused before anything is built, and numbers must be finite and within MAX_MAGNITUDE, so a hostile
file costs little and ends in one WorldError line naming the file and field.
"""
from __future__ import annotations

import math
import os
import re
import reprlib
import stat
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from epuck_ros import untrusted_yaml
from epuck_ros.model import RobotModel
from epuck_ros.spatial import close_pairs

CONTACT_TOLERANCE = 1e-6
"""m; a disc this close to an obstacle touches it (a pushed-out disc sits at exactly its radius)."""

_PUSH_ITERATIONS = 4
"""Push-out passes per step; two obstacles meeting at a corner need more than one."""

_ALL_OBSTACLES_UP_TO = 1024
"""Rays x obstacles up to which every ray is tested against every obstacle: cheaper than the grid's lookups."""
_ALL_OBSTACLES_BELOW = 16
"""Fewer obstacles than this: the robots near something test their rays against all of them, no grid lookups."""

MAX_FILE_BYTES = 8 * 2 ** 20
"""A world file larger than this is refused unread (10,000 robots take about 0.6 MB)."""
MAX_NESTING = 16
"""Deepest YAML nesting accepted (the format needs 4); deeper input is refused before it is built."""
MAX_MAGNITUDE = 1e4
"""Largest absolute value (m or rad) of any number in a world: far beyond any arena, far below overflow."""
ROBOT_GAP = 0.01
"""m between the bodies of robots placed by `place_robots`, so none starts touching another."""


class WorldError(ValueError):
    """A world that cannot be used; the message names the file, the field and what is wrong."""


@dataclass(frozen=True)
class Box:
    """A rectangular obstacle centred at (x, y), rotated by yaw (rad)."""

    x: float
    y: float
    size_x: float
    size_y: float
    yaw: float = 0.0


@dataclass(frozen=True)
class Cylinder:
    """A round obstacle centred at (x, y)."""

    x: float
    y: float
    radius: float


ROBOT_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*\Z')
ROBOT_NAME_MAX = 100
"""Characters in a robot's name at most: its topics (`<name>/camera/camera_info` the longest planned, under the
simulator's namespace) must stay within rmw's 247 characters for a full topic name, or the simulator dies
creating them (a valid 240-character name did)."""
"""A robot's name is one ROS name token: its topics and frames live under it (`epuck3/odom`)."""


@dataclass(frozen=True)
class RobotStart:
    """Where a robot starts and the name its ROS ports live under."""

    name: str
    x: float
    y: float
    yaw: float = 0.0

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.yaw)


ONE_ROBOT = (RobotStart('epuck', 0.0, 0.0, 0.0),)


@dataclass(frozen=True, init=False)
class World:
    """Arena, obstacles and the robots' start poses; built once, then queried every step."""

    arena_size: tuple[float, float] = (1.0, 1.0)
    boxes: tuple[Box, ...] = ()
    cylinders: tuple[Cylinder, ...] = ()
    robots: tuple[RobotStart, ...] = ONE_ROBOT
    _geometry: _Geometry = field(init=False, repr=False, compare=False)

    def __init__(self, arena_size: Iterable[float] = (1.0, 1.0), boxes: Iterable[Box] = (),
                 cylinders: Iterable[Cylinder] = (), robots: Iterable[RobotStart] = ONE_ROBOT,
                 start_pose: Iterable[float] | None = None) -> None:
        """`start_pose` is the one-robot form kept for older callers: one robot named `epuck` there."""
        if start_pose is not None:
            if robots is not ONE_ROBOT:
                raise WorldError('robots: give either robots or start_pose, not both')
            robots = (RobotStart(ONE_ROBOT[0].name, *start_pose),)
        object.__setattr__(self, 'arena_size', tuple(float(v) for v in arena_size))
        object.__setattr__(self, 'boxes', tuple(boxes))
        object.__setattr__(self, 'cylinders', tuple(cylinders))
        robots = tuple(RobotStart(str(r.name), float(r.x), float(r.y), float(r.yaw)) for r in robots)
        object.__setattr__(self, 'robots', robots)
        problem = _name_problem(robots)
        if problem:
            raise WorldError(f'robots: {problem}')
        object.__setattr__(self, '_geometry', _Geometry(self))

    @property
    def start_pose(self) -> tuple[float, float, float]:
        """The first robot's start pose (the one-robot API)."""
        return self.robots[0].pose

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(robot.name for robot in self.robots)

    def with_robots(self, robots: Iterable[RobotStart]) -> World:
        """The same arena and obstacles with other robots."""
        return World(self.arena_size, self.boxes, self.cylinders, tuple(robots))

    def cast_rays(self, origins: np.ndarray, yaws: np.ndarray, max_range: float) -> np.ndarray:
        """Distance (K,) from each origin (K, 2) inside the arena along its yaw (K,) to the first wall or obstacle;
        inf beyond max_range."""
        yaws = np.asarray(yaws, dtype=float).ravel()
        origins = np.asarray(origins, dtype=float).reshape(-1, 2)
        return self.ray_distances(origins[:, 0], origins[:, 1], np.cos(yaws), np.sin(yaws), max_range)

    def ray_distances(self, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray, max_range: float,
                      centres: np.ndarray | None = None, spread: float = 0.0) -> np.ndarray:
        """Distance along rays (origins ox, oy and unit directions, each (S, G): S rays in each of G groups, one
        group a column) to the first wall or obstacle; inf beyond max_range. `centres` (G, 2): each group's rays
        start within `spread` of it (a robot's sensors), so obstacles are looked up once per group; without,
        once per ray (the arrays may then have any shape).

        Walls and box edges are segments, cylinders circles, in NumPy over all rays at once. A few rays or
        obstacles: every ray against every one. Many: a grid of cells (see _ObstacleGrid) gives each group only
        the obstacles near it, and only groups near a wall or obstacle are computed at all, so the cost per ray
        does not grow with the number of obstacles. The obstacles are the leading axis and the rays the last
        (contiguous) one: NumPy then runs one long inner loop per obstacle instead of one short loop per ray
        (with the hit test in fewer calls, 50 robots' rays cost 82 us instead of 96, measured).
        """
        g = self._geometry
        shape = ox.shape
        with np.errstate(divide='ignore', invalid='ignore'):   # parallel to an edge: +-inf, or NaN = a miss
            if dir_x.size * (g.edge_total + g.cylinder_count) <= _ALL_OBSTACLES_UP_TO:
                nearest = g.rays_to_edges(ox, oy, dir_x, dir_y).min(axis=0)   # walls and boxes
                if g.cylinder_count:
                    nearest = np.minimum(nearest, g.rays_to_cylinders(ox, oy, dir_x, dir_y).min(axis=0))
            else:
                if centres is None:
                    ox, oy, dir_x, dir_y = (a.reshape(1, -1) for a in (ox, oy, dir_x, dir_y))
                    centres, spread = np.column_stack([ox[0], oy[0]]), 0.0
                nearest = self._nearest_on_grid(ox, oy, dir_x, dir_y, centres, max_range + spread)
        nearest[~(nearest <= max_range)] = np.inf
        return nearest.reshape(shape)

    def _nearest_on_grid(self, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray,
                         centres: np.ndarray, reach: float) -> np.ndarray:
        """Distance (S, G) along each group's rays to the walls and to the box edges and cylinders (all of them, or
        those the grid lists for the group's cell); only groups the clearance map puts within `reach` of
        something are computed."""
        g = self._geometry
        nearest = np.full(ox.shape, np.inf)
        rows = g.clearance().near(centres, reach).nonzero()[0]
        if not len(rows):
            return nearest
        x, y, dx, dy = ox[:, rows], oy[:, rows], dir_x[:, rows], dir_y[:, rows]
        if g.box_count + g.cylinder_count <= _ALL_OBSTACLES_BELOW:   # a few: each ray against all, no lookups
            found = g.rays_to_edges(x, y, dx, dy).min(axis=0)
            if g.cylinder_count:
                found = np.minimum(found, g.rays_to_cylinders(x, y, dx, dy).min(axis=0))
        else:
            found = np.minimum((np.copysign(g.half_x, dx) - x) / dx, (np.copysign(g.half_y, dy) - y) / dy)
            grid = g.grid(reach)
            cells = grid.cell_of(centres[rows, 0], centres[rows, 1])
            if g.box_count:
                found = np.minimum(found, g.rays_to_edges(x, y, dx, dy, grid.edge_ids[cells].T[:, None, :]).min(axis=0))
            if g.cylinder_count:
                found = np.minimum(found, g.rays_to_cylinders(x, y, dx, dy,
                                                              grid.cylinder_ids[cells].T[:, None, :]).min(axis=0))
        nearest[:, rows] = found
        return nearest

    def resolve_collision(self, xy: np.ndarray, radius: float,
                          previous: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each disc (N, 2) moved out of every wall and obstacle it overlaps; (xy (N, 2), touching (N,) bool).

        The same rule as `push_disc_out`, for all discs at once in NumPy (the simulator's path for many robots);
        `previous` (N, 2), the discs' last clear positions, is where a disc goes back to if it cannot be freed.
        """
        g = self._geometry
        xy = np.array(xy, dtype=float).reshape(-1, 2)
        touching = np.zeros(len(xy), dtype=bool)
        rows = g.clearance().near(xy, radius + CONTACT_TOLERANCE).nonzero()[0]
        if not len(rows):
            return xy, touching
        # Candidates within a diameter (not just a radius) of the cell: a disc pushed by up to its radius
        # still finds every obstacle it may meet on the way.
        grid = g.grid(2.0 * radius + CONTACT_TOLERANCE)
        cells = grid.cell_of(xy[rows, 0], xy[rows, 1])
        box_ids, cylinder_ids = grid.box_ids[cells], grid.cylinder_ids[cells]
        x, y = xy[rows, 0:1].copy(), xy[rows, 1:2].copy()
        distance, normal_x, normal_y = g.surfaces(x, y, box_ids, cylinder_ids)
        touching[rows] = (distance < radius + CONTACT_TOLERANCE).any(axis=1)
        active = np.arange(len(rows))
        limit = radius
        for _ in range(_PUSH_ITERATIONS):
            overlap = np.where(distance < limit, radius - distance, 0.0)
            pushed = overlap.any(axis=1)
            active, overlap = active[pushed], overlap[pushed]
            if not len(active):
                break
            x[active, 0] += (overlap * normal_x[pushed]).sum(axis=1)
            y[active, 0] += (overlap * normal_y[pushed]).sum(axis=1)
            distance, normal_x, normal_y = g.surfaces(x[active], y[active], box_ids[active], cylinder_ids[active])
            limit = radius - CONTACT_TOLERANCE
        else:
            stuck = active[(distance < limit).any(axis=1)]
            if previous is not None and len(stuck):
                x[stuck, 0], y[stuck, 0] = previous[rows[stuck], 0], previous[rows[stuck], 1]
        xy[rows, 0], xy[rows, 1] = x[:, 0], y[:, 0]
        return xy, touching

    def push_disc_out(self, x: float, y: float, radius: float,
                      previous: tuple[float, float] | None = None) -> tuple[float, float, bool]:
        """One disc moved out of what it overlaps, along each penetration normal; (x, y, touching).

        Plain floats: for one robot this is several times cheaper than the NumPy `resolve_collision`, which
        follows the same rule (a test checks they agree).

        A disc driven into a wall ends touching it, so it slides along. A few passes settle a disc pushed into
        a corner by two obstacles; if they cannot (a gap narrower than the disc), it goes back to `previous`.
        Touching means closer than CONTACT_TOLERANCE: a pushed-out disc sits at exactly its radius.
        """
        surfaces = self._geometry.surfaces_within(x, y, radius + CONTACT_TOLERANCE)
        touching = bool(surfaces)
        for _ in range(_PUSH_ITERATIONS):
            overlaps = [(radius - distance, nx, ny) for _, distance, nx, ny in surfaces if distance < radius]
            if not overlaps:
                return x, y, touching
            x += sum(depth * nx for depth, nx, _ in overlaps)
            y += sum(depth * ny for depth, _, ny in overlaps)
            surfaces = self._geometry.surfaces_within(x, y, radius - CONTACT_TOLERANCE)
        if surfaces and previous is not None:
            x, y = previous
        return x, y, touching

    def anything_within(self, x: float, y: float, distance: float) -> bool:
        """Whether any wall or obstacle surface is closer than `distance` to (x, y); cheap when nothing is."""
        return bool(self._geometry.surfaces_within(x, y, distance))

    def surfaces_near(self, x: float, y: float, distance: float) -> list[int]:
        """Indexes of the surfaces closer than `distance` to (x, y) (for `cast_near`); empty when nothing is."""
        return [index for index, *_ in self._geometry.surfaces_within(x, y, distance)]

    def cast_near(self, surfaces: list[int], rays: list[tuple[float, float, float, float]],
                  max_range: float) -> list[float]:
        """Distance along each ray (origin x, y, unit direction x, y) to the first of the `surfaces`; inf beyond
        max_range. `surfaces` must hold every surface a ray can reach within max_range (`surfaces_near` around
        a point the rays start near, with the reach); one robot's rays, each step.

        Plain floats, with `ray_distances`' formulas operation for operation, so the distances equal its to the
        bit (a test checks): 8 rays against the surfaces near one robot cost 6 us with the search for them,
        against 40 us for `ray_distances` testing every edge of the default world in NumPy (measured). In a
        world so large that `ray_distances` would use its grid, the rays go there.
        """
        g = self._geometry
        if len(rays) * (g.edge_total + g.cylinder_count) > _ALL_OBSTACLES_UP_TO:
            return self.ray_distances(*np.array(rays).T, max_range).tolist()
        edges = [edge for index in surfaces for edge in g.surface_edges[index]]
        circles = [g.surface_circles[index] for index in surfaces if g.surface_circles[index] is not None]
        distances = []
        for ox, oy, dx, dy in rays:
            nearest = math.inf
            for start_x, start_y, edge_x, edge_y in edges:
                denominator = dx * edge_y - dy * edge_x
                if denominator == 0.0:
                    continue   # parallel: NumPy's inf or NaN, a miss
                inverse = 1.0 / denominator
                to_x, to_y = start_x - ox, start_y - oy
                along_ray = (to_x * edge_y - to_y * edge_x) * inverse
                along_edge = (to_x * dy - to_y * dx) * inverse
                if along_ray >= 0.0 and along_edge >= 0.0 and along_edge <= 1.0 and along_ray < nearest:
                    nearest = along_ray
            for centre_x, centre_y, radius in circles:
                from_x, from_y = ox - centre_x, oy - centre_y
                half_b = from_x * dx + from_y * dy
                discriminant = half_b * half_b - (from_x * from_x + from_y * from_y - radius * radius)
                root = -half_b - math.sqrt(max(discriminant, 0.0))
                if not (discriminant < 0.0 or root < 0.0) and root < nearest:
                    nearest = root
            distances.append(nearest if nearest <= max_range else math.inf)
        return distances

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """Distance (N,) from each point (N, 2) to the nearest wall or obstacle surface (0 inside an obstacle)."""
        return np.array([max(0.0, min(d for _, d, _, _ in self._geometry.surfaces_within(x, y, math.inf)))
                         for x, y in np.asarray(xy, dtype=float).reshape(-1, 2).tolist()])

    def discs_clear(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """(N,) whether a disc of `radius` at each point (N, 2) is inside the arena and overlaps no obstacle:
        every point at once, each against the obstacles the grid lists near it."""
        g = self._geometry
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        grid = g.grid(radius)
        cells = grid.cell_of(xy[:, 0], xy[:, 1])
        clear = np.empty(len(xy), dtype=bool)
        for start in range(0, len(xy), 4096):   # in chunks: bounded memory for any number of points
            rows = slice(start, start + 4096)
            distance, _, _ = g.surfaces(xy[rows, 0:1], xy[rows, 1:2], grid.box_ids[cells[rows]],
                                        grid.cylinder_ids[cells[rows]])
            clear[rows] = distance.min(axis=1) >= radius
        return clear

    def overlapping(self, x: float, y: float, radius: float) -> list[str]:
        """Field paths (`boxes[2]`, `arena.size` for a wall) of everything a disc at (x, y) overlaps."""
        names = (['arena.size'] * 4 + [f'boxes[{i}]' for i in range(len(self.boxes))]
                 + [f'cylinders[{i}]' for i in range(len(self.cylinders))])
        return [names[index] for index, distance, _, _ in self._geometry.surfaces_within(x, y, radius)]

    def to_dict(self) -> dict[str, Any]:
        """The world in the YAML file format, with plain floats (yaml.safe_dump writes it; world_from_dict reads it)."""
        return {
            'arena': {'size': list(self.arena_size)},
            'boxes': [{'position': [b.x, b.y], 'size': [b.size_x, b.size_y], 'yaw': b.yaw} for b in self.boxes],
            'cylinders': [{'position': [c.x, c.y], 'radius': c.radius} for c in self.cylinders],
        } | self._robots_dict()

    def _robots_dict(self) -> dict[str, Any]:
        """`robot:` for the single default-named robot (what one-robot readers expect), else the `robots:` list."""
        if self.robots[:1] == self.robots and self.robots[0].name == ONE_ROBOT[0].name:
            return {'robot': {'start': list(self.start_pose)}}
        return {'robots': [{'name': r.name, 'start': list(r.pose)} for r in self.robots]}


class _Geometry:
    """A World's walls and obstacles prepared once: float tuples for one disc, NumPy arrays for many.

    A one-disc query is one point against a few obstacles, where NumPy's per-call overhead would cost more
    than the arithmetic: plain floats, with a bounding-circle test that skips every obstacle out of reach.
    Rays and many discs go to NumPy, each against the obstacles a grid lists near it. The obstacle arrays end
    with one dummy obstacle far away, which pads the grid's rows.
    """

    def __init__(self, world: World) -> None:
        self.half_x, self.half_y = world.arena_size[0] / 2.0, world.arena_size[1] / 2.0
        self.boxes = [(b.x, b.y, math.cos(b.yaw), math.sin(b.yaw), b.size_x / 2, b.size_y / 2,
                       math.hypot(b.size_x, b.size_y) / 2) for b in world.boxes]
        self.cylinders = [(c.x, c.y, c.radius) for c in world.cylinders]
        self.box_count, self.cylinder_count = len(self.boxes), len(self.cylinders)
        far = 1e9
        (self.box_x, self.box_y, self.box_cos, self.box_sin, self.box_half_x, self.box_half_y,
         self.box_bound) = np.array(self.boxes + [(far, far, 1.0, 0.0, 1.0, 1.0, 1.0)]).T.copy()
        self.cyl_x, self.cyl_y, self.cyl_radius = np.array(self.cylinders + [(far, far, 1.0)]).T.copy()
        # Edges as segments (start, start-to-end vector) for rays: the 4 walls, 4 per box, a far dummy edge.
        hx, hy = self.half_x, self.half_y
        corners = [[(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)]] + [_box_corners(box) for box in world.boxes]
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
        self._grids: dict[float, _ObstacleGrid] = {}
        self._clearance: _ClearanceMap | None = None

    def clearance(self) -> _ClearanceMap:
        """The clearance map (built on first use, then kept)."""
        if self._clearance is None:
            self._clearance = _ClearanceMap(self)
        return self._clearance

    def grid(self, reach: float) -> _ObstacleGrid:
        """The obstacle grid for queries that reach `reach` from a point (built on first use, then kept)."""
        if reach not in self._grids:
            self._grids[reach] = _ObstacleGrid(self, reach)
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

    def surfaces_within(self, x: float, y: float, reach: float) -> list[tuple[int, float, float, float]]:
        """(index, signed distance, normal x, normal y) of each surface closer than `reach` to the point (x, y).

        Indexes run over the walls at -x, -y, +x, +y, then the boxes, then the cylinders. The normal points from
        the surface towards the point; the distance is negative inside an obstacle (the normal then points to
        the nearest way out), so a push of (radius - distance) along the normal frees a disc from that surface.
        """
        found = []   # the walls one by one: a third of the cost of a loop over them (measured)
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
                distance, local_nx, local_ny = _box_distance(dx * cos + dy * sin, dy * cos - dx * sin, half_x, half_y)
                if distance < reach:
                    found.append((index, distance, local_nx * cos - local_ny * sin, local_nx * sin + local_ny * cos))
        for index, (cx, cy, radius) in enumerate(self.cylinders, start=4 + len(self.boxes)):
            dx, dy = x - cx, y - cy
            centre_distance = math.hypot(dx, dy)
            if centre_distance - radius < reach:
                nx, ny = (dx / centre_distance, dy / centre_distance) if centre_distance > 0.0 else (1.0, 0.0)
                found.append((index, centre_distance - radius, nx, ny))
        return found


def _box_distance(local_x: float, local_y: float, half_x: float, half_y: float) -> tuple[float, float, float]:
    """Signed distance from a point (in the box frame) to an axis-aligned box, and the unit normal there."""
    gap_x = abs(local_x) - half_x
    gap_y = abs(local_y) - half_y
    sign_x, sign_y = math.copysign(1.0, local_x), math.copysign(1.0, local_y)
    if gap_x <= 0.0 and gap_y <= 0.0:  # inside: out through the nearest face
        return (gap_x, sign_x, 0.0) if gap_x > gap_y else (gap_y, 0.0, sign_y)
    out_x, out_y = max(gap_x, 0.0), max(gap_y, 0.0)
    distance = math.hypot(out_x, out_y)
    return distance, sign_x * out_x / distance, sign_y * out_y / distance


class _ObstacleGrid:
    """Square cells over the arena, each listing the boxes and cylinders within `reach` of any point in it.

    A query from a point then tests only its cell's few obstacles: the cost per robot or ray stays flat as a
    world grows to thousands of obstacles. Rows are padded with the dummy obstacle (index B or C).
    """

    def __init__(self, geometry: _Geometry, reach: float) -> None:
        # Cells at least `reach` wide (neighbours need not be looked at) and at most ~250,000 of them (a
        # 10 km arena allowed by MAX_MAGNITUDE must not take gigabytes; its cells then list more obstacles).
        self.cell = max(reach, 0.05, math.sqrt(4.0 * geometry.half_x * geometry.half_y / 250_000))
        self.columns = max(1, math.ceil(2.0 * geometry.half_x / self.cell))
        self.rows = max(1, math.ceil(2.0 * geometry.half_y / self.cell))
        self.left, self.bottom = -geometry.half_x, -geometry.half_y
        bounds = ([(x, y, bound) for x, y, *_, bound in geometry.boxes],
                  [(x, y, radius) for x, y, radius in geometry.cylinders])
        (self.box_count, self.box_ids), (self.cylinder_count, self.cylinder_ids) = (
            self._lists(shapes, reach) for shapes in bounds)
        # A box's four edges go wherever the box goes (edge 4 + 4 b + k is edge k of box b; 0-3 are the walls).
        self.edge_count = 4 * self.box_count
        edges = 4 + 4 * self.box_ids[:, :, None] + np.arange(4)
        self.edge_ids = np.where(self.box_ids[:, :, None] < len(geometry.boxes), edges,
                                 geometry.edge_total).reshape(len(self.box_ids), -1)

    def cell_of(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat cell index of each point (points off the arena count in the nearest border cell)."""
        column = np.minimum(np.maximum(((x - self.left) / self.cell).astype(np.int64), 0), self.columns - 1)
        row = np.minimum(np.maximum(((y - self.bottom) / self.cell).astype(np.int64), 0), self.rows - 1)
        return row * self.columns + column

    def _lists(self, shapes: list[tuple[float, float, float]], reach: float) -> tuple[np.ndarray, np.ndarray]:
        """(count per cell, ids per cell padded with len(shapes)) for shapes given as bounding circles."""
        cells, ids = [np.empty(0, dtype=np.int64)], [np.empty(0, dtype=np.int64)]
        for index, (x, y, bound) in enumerate(shapes):   # each shape: the cells of its bounding square, then
            span = bound + reach                         # those whose nearest point is within reach
            columns = np.arange(*np.clip([math.floor((x - span - self.left) / self.cell),
                                          math.floor((x + span - self.left) / self.cell) + 1], 0, self.columns))
            rows = np.arange(*np.clip([math.floor((y - span - self.bottom) / self.cell),
                                       math.floor((y + span - self.bottom) / self.cell) + 1], 0, self.rows))
            column, row = (v.ravel() for v in np.meshgrid(columns, rows))
            low_x, low_y = self.left + column * self.cell, self.bottom + row * self.cell
            gap_x = np.maximum(np.maximum(low_x - x, x - low_x - self.cell), 0.0)
            gap_y = np.maximum(np.maximum(low_y - y, y - low_y - self.cell), 0.0)
            near = np.hypot(gap_x, gap_y) < span
            cells.append(row[near] * self.columns + column[near])
            ids.append(np.full(int(near.sum()), index, dtype=np.int64))
        cells, ids = np.concatenate(cells), np.concatenate(ids)
        order = np.lexsort((ids, cells))
        cells, ids = cells[order], ids[order]
        counts = np.bincount(cells, minlength=self.columns * self.rows)
        table = np.full((len(counts), max(1, int(counts.max(initial=0)))), len(shapes), dtype=np.int64)
        table[cells, np.arange(len(cells)) - (np.cumsum(counts) - counts)[cells]] = ids
        return counts, table


class _ClearanceMap:
    """A fine raster over the arena holding, per cell, a lower bound of the distance from any point in it to the
    nearest wall or obstacle (capped at CAP).

    Most robots are far from everything most of the time: one lookup per robot says which ones need no
    collision test and whose rays cannot reach a wall or obstacle, before any per-obstacle work. At most
    about 250,000 cells (5 mm in a 1 m arena, 3 cm in a 15 m one); the bound is the cell centre's distance
    less half the cell's diagonal (distance changes by at most that much within a cell).
    """

    CAP = 0.25
    """m; queries ask about less than this (a robot's sensing reach is about 0.14 m)."""

    def __init__(self, geometry: _Geometry) -> None:
        self.half_x, self.half_y = geometry.half_x, geometry.half_y
        self.cell = max(0.005, math.sqrt(4.0 * self.half_x * self.half_y / 250_000))
        self.columns = max(1, math.ceil(2.0 * self.half_x / self.cell))
        self.rows = max(1, math.ceil(2.0 * self.half_y / self.cell))
        grid = geometry.grid(self.CAP)
        centres_x = -self.half_x + (np.arange(self.columns) + 0.5) * self.cell
        self.bound = np.empty(self.rows * self.columns)
        for row in range(0, self.rows, max(1, 20_000 // self.columns)):   # in chunks: bounded memory
            ys = -self.half_y + (np.arange(row, min(row + max(1, 20_000 // self.columns), self.rows)) + 0.5) * self.cell
            x, y = (v.ravel() for v in np.meshgrid(centres_x, ys))
            cells = grid.cell_of(x, y)
            distance, _, _ = geometry.surfaces(x[:, None], y[:, None], grid.box_ids[cells], grid.cylinder_ids[cells])
            self.bound[row * self.columns:row * self.columns + len(x)] = np.minimum(distance.min(axis=1), self.CAP)
        self.bound -= self.cell * math.sqrt(0.5)
        self._half, self._last = np.array([self.half_x, self.half_y]), np.array([self.columns - 1, self.rows - 1])

    def near(self, xy: np.ndarray, reach: float) -> np.ndarray:
        """(K,) whether a wall or obstacle may be within `reach` (< CAP) of each point (K, 2); False: surely not."""
        cells = np.minimum(np.maximum(((xy + self._half) / self.cell).astype(np.int64), 0), self._last)
        return self.bound[cells[:, 1] * self.columns + cells[:, 0]] < reach


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


def _box_corners(box: Box) -> list[tuple[float, float]]:
    cos, sin = math.cos(box.yaw), math.sin(box.yaw)
    hx, hy = box.size_x / 2.0, box.size_y / 2.0
    return [(box.x + cos * lx - sin * ly, box.y + sin * lx + cos * ly)
            for lx, ly in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]


def default_world() -> World:
    """The course's RectangleArena (1 m x 1 m) with three 0.1 m boxes; `worlds/default.yaml` holds the same.

    The boxes stand in the left half, clear of where the course behaviours drive from the origin (the 0.078 m
    circle, the 0.31 m rectangle turning either way, the straight run to the +x wall), and leave an avoiding
    robot gaps of at least 0.1 m everywhere.
    """
    return World(arena_size=(1.0, 1.0),
                 boxes=(Box(-0.3, 0.3, 0.1, 0.1), Box(-0.25, 0.0, 0.1, 0.1, 0.5), Box(-0.3, -0.3, 0.1, 0.1)))


def load_world(path: str | Path, robot_radius: float = RobotModel().body_radius) -> World:
    """Read and check a world YAML file; any problem raises WorldError naming the file and the field.

    The file is opened without blocking and must be a regular file (a named pipe would otherwise hang the
    reader) no larger than MAX_FILE_BYTES.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, 'O_NONBLOCK', 0))
    except FileNotFoundError:
        raise WorldError(f'{path}: file not found') from None
    except OSError as error:
        raise WorldError(f'{path}: cannot read the file: {error.strerror}') from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise WorldError(f'{path}: cannot read the file: not a regular file (a directory, pipe or device)')
        if info.st_size > MAX_FILE_BYTES:
            raise WorldError(f'{path}: file too large ({info.st_size} bytes, at most {MAX_FILE_BYTES})')
        with os.fdopen(os.dup(fd), 'rb') as file:
            data = file.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        raise WorldError(f'{path}: cannot read the file: {error.strerror}') from None
    finally:
        os.close(fd)
    if len(data) > MAX_FILE_BYTES:
        raise WorldError(f'{path}: file too large (more than {MAX_FILE_BYTES} bytes)')
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as error:
        raise WorldError(f'{path}: not UTF-8 text (byte {error.start})') from None
    return world_from_yaml(text, str(path), robot_radius)


def world_from_yaml(text: str, source: str = '<yaml>', robot_radius: float = RobotModel().body_radius) -> World:
    """A World from world-file text (also a bag's `world` topic): YAML checked for aliases and depth, then built."""
    if len(text) > MAX_FILE_BYTES:
        raise WorldError(f'{source}: too large ({len(text)} characters, at most {MAX_FILE_BYTES})')
    try:
        data = untrusted_yaml.load(text, MAX_NESTING)
    except untrusted_yaml.UntrustedYamlError as error:
        raise WorldError(f'{source}: {error}') from None
    return world_from_dict({} if data is None else data, source, robot_radius)


def world_from_dict(data: Any, source: str = '<dict>', robot_radius: float = RobotModel().body_radius) -> World:
    """Build a World from the file format (see the module docstring), checking every field and the start poses."""
    fields = _FieldReader(source)
    top = fields.mapping(data, '<top level>', ('arena', 'boxes', 'cylinders', 'robot', 'robots'))
    arena = fields.section(top, 'arena', ('size',))
    if top.get('robot') is not None and top.get('robots') is not None:
        raise fields.fail('robots', 'give either `robots` (a list) or `robot` (one robot), not both')
    if top.get('robots') is not None:
        robots = tuple(fields.each(top, 'robots', ('name', 'start'), _read_robot))
        if not robots:
            raise fields.fail('robots', 'the list is empty (leave it out for one robot at the origin)')
    else:
        robot = fields.section(top, 'robot', ('start',))
        robots = (RobotStart(ONE_ROBOT[0].name, *fields.vector(robot.get('start', [0.0, 0.0, 0.0]), 'robot.start', 3)),)
    problem = _name_problem(robots)
    if problem:
        raise fields.fail('robots', problem)
    world = World(arena_size=fields.vector(arena.get('size', [1.0, 1.0]), 'arena.size', 2, positive=True),
                  boxes=tuple(fields.each(top, 'boxes', ('position', 'size', 'yaw'), _read_box)),
                  cylinders=tuple(fields.each(top, 'cylinders', ('position', 'radius'), _read_cylinder)),
                  robots=robots)
    _check_obstacles_are_inside(world, source)
    _check_robots_are_clear(world, robot_radius, source, 'robots' if 'robots' in top else 'robot')
    return world


def _check_obstacles_are_inside(world: World, source: str) -> None:
    """Every box and cylinder lies on the arena's floor, whole (touching a wall is fine): one outside was accepted
    and silently missing from every picture and every sensor, like a typo nobody is told about."""
    half_x, half_y = world.arena_size[0] / 2.0 + 1e-9, world.arena_size[1] / 2.0 + 1e-9
    for index, box in enumerate(world.boxes):
        if any(abs(x) > half_x or abs(y) > half_y for x, y in _box_corners(box)):
            raise WorldError(f'{source}: boxes[{index}].position: the box at ({box.x}, {box.y}) of size '
                             f'{box.size_x} x {box.size_y} m does not lie whole inside the {world.arena_size[0]} m x '
                             f'{world.arena_size[1]} m arena (centred on the origin)')
    for index, cylinder in enumerate(world.cylinders):
        if abs(cylinder.x) + cylinder.radius > half_x or abs(cylinder.y) + cylinder.radius > half_y:
            raise WorldError(f'{source}: cylinders[{index}].position: the cylinder at ({cylinder.x}, {cylinder.y}) '
                             f'of radius {cylinder.radius} m does not lie whole inside the {world.arena_size[0]} m x '
                             f'{world.arena_size[1]} m arena (centred on the origin)')


def _read_robot(fields: _FieldReader, item: Mapping[str, Any], path: str) -> RobotStart:
    name = item.get('name', f'epuck{path[path.index("[") + 1:-1]}')
    if not isinstance(name, str) or not ROBOT_NAME.match(name) or '__' in name:
        raise fields.fail(f'{path}.name', f'expected a ROS name ([A-Za-z_][A-Za-z0-9_]*, no "__"), got '
                                          f'{_describe(name)}')
    if len(name) > ROBOT_NAME_MAX:
        raise fields.fail(f'{path}.name', f'at most {ROBOT_NAME_MAX} characters (its topics must fit in a ROS '
                                          f'topic name), got {len(name)}')
    return RobotStart(name, *fields.vector(fields.required(item, 'start', path), f'{path}.start', 3))


def _name_problem(robots: tuple[RobotStart, ...]) -> str | None:
    """Why these robots' names cannot be used together (none, invalid, repeated), or None."""
    if not robots:
        return 'a world needs at least one robot'
    seen: dict[str, int] = {}
    for index, robot in enumerate(robots):
        if not ROBOT_NAME.match(robot.name) or '__' in robot.name or len(robot.name) > ROBOT_NAME_MAX:
            return (f'robots[{index}].name {untrusted_yaml.cut(repr(robot.name), 40)} is not a ROS name of at most '
                    f'{ROBOT_NAME_MAX} characters')
        if robot.name in seen:
            return f'robots[{index}] and robots[{seen[robot.name]}] are both named {robot.name!r}'
        seen[robot.name] = index
    return None


def _read_box(fields: _FieldReader, item: Mapping[str, Any], path: str) -> Box:
    x, y = fields.vector(fields.required(item, 'position', path), f'{path}.position', 2)
    size_x, size_y = fields.vector(fields.required(item, 'size', path), f'{path}.size', 2, positive=True)
    return Box(x, y, size_x, size_y, fields.number(item.get('yaw', 0.0), f'{path}.yaw'))


def _read_cylinder(fields: _FieldReader, item: Mapping[str, Any], path: str) -> Cylinder:
    x, y = fields.vector(fields.required(item, 'position', path), f'{path}.position', 2)
    return Cylinder(x, y, fields.number(fields.required(item, 'radius', path), f'{path}.radius', positive=True))


def _check_robots_are_clear(world: World, robot_radius: float, source: str, field_name: str) -> None:
    """Each robot must start inside the arena touching nothing (not even another robot), or the first step would
    teleport it; the error names the robot's field (`robots[2].start`, or `robot.start` in the one-robot form)."""
    starts = np.array([robot.pose[:2] for robot in world.robots])
    for index in np.flatnonzero(~world.discs_clear(starts, robot_radius + CONTACT_TOLERANCE))[:1].tolist():
        robot = world.robots[index]
        path = f'{field_name}[{index}].start' if field_name == 'robots' else 'robot.start'
        overlapping = world.overlapping(robot.x, robot.y, robot_radius + CONTACT_TOLERANCE)
        where = f'the robot {robot.name!r} (radius {robot_radius} m) at ({robot.x}, {robot.y})'
        if 'arena.size' in overlapping:
            width, height = world.arena_size
            raise WorldError(f'{source}: {path}: {where} is not inside the {width} m x {height} m arena '
                             f'(|x| < {width / 2 - robot_radius:.4g}, |y| < {height / 2 - robot_radius:.4g})')
        raise WorldError(f'{source}: {path}: {where} overlaps {", ".join(overlapping)}')
    for first, second in zip(*close_pairs(starts, 2.0 * robot_radius + CONTACT_TOLERANCE)):
        first, second = sorted((int(first), int(second)))
        a, b = world.robots[first], world.robots[second]
        raise WorldError(f'{source}: {field_name}[{second}].start: the robot {b.name!r} at ({b.x}, {b.y}) overlaps '
                         f'{field_name}[{first}] ({a.name!r} at ({a.x}, {a.y})): centres closer than '
                         f'{2 * robot_radius:.4g} m')


def place_robots(world: World, count: int, seed: int, model: RobotModel = RobotModel()) -> World:
    """`world` with `count` robots named epuck0.. placed clear of walls, obstacles and each other; seeded.

    Candidate spots are a hexagonal lattice (the densest packing of discs) with ROBOT_GAP between bodies, keeping
    those clear of every wall and obstacle; a seeded draw picks `count` of them, jitters each by at most a
    quarter gap and gives it a random heading. So placement never fails when there is room, the same seed always
    gives the same world, and "more than fit" means more than the lattice holds.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise WorldError(f'robots: the number of robots must be a positive integer, got {_describe(count)}')
    radius = model.body_radius
    jitter = ROBOT_GAP / 4.0
    half_x, half_y = (size / 2.0 - radius - jitter - CONTACT_TOLERANCE for size in world.arena_size)
    # at most ~2 million spots, so a huge arena costs no more than a big one (robots then stand farther apart)
    spacing = max(2.0 * radius + ROBOT_GAP, math.sqrt(max(half_x, 0.0) * max(half_y, 0.0) * 4.0 / 2e6))
    rows = np.arange(-half_y, half_y + 1e-12, spacing * math.sqrt(3.0) / 2.0) if half_y >= 0 else np.empty(0)
    spots = []
    for row, y in enumerate(rows):
        xs = np.arange(-half_x + (spacing / 2.0 if row % 2 else 0.0), half_x + 1e-12, spacing)
        spots.append(np.column_stack([xs, np.full(len(xs), y)]))
    spots = np.concatenate(spots) if spots else np.empty((0, 2))
    if len(spots):
        spots = spots[world.discs_clear(spots, radius + jitter + 2 * CONTACT_TOLERANCE)]
    if count > len(spots):
        raise WorldError(f'robots: {count} robots do not fit in this world (room for {len(spots)} e-pucks of '
                         f'radius {radius} m with {ROBOT_GAP} m between them)')
    rng = np.random.default_rng(seed)
    chosen = spots[np.sort(rng.choice(len(spots), size=count, replace=False))]
    angle = rng.uniform(-math.pi, math.pi, size=count)
    offset = jitter * np.sqrt(rng.uniform(0.0, 1.0, size=count))
    chosen = chosen + offset[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    yaw = rng.uniform(-math.pi, math.pi, size=count)
    return world.with_robots(RobotStart(f'epuck{i}', x, y, heading)
                             for i, ((x, y), heading) in enumerate(zip(chosen.tolist(), yaw.tolist())))


class _FieldReader:
    """Typed access to the world file's fields; every failure is a WorldError naming the file and field path."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, path: str, problem: str) -> WorldError:
        return WorldError(f'{self.source}: {path}: {problem}')

    def mapping(self, value: Any, path: str, keys: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(path, f'expected a mapping with keys {", ".join(keys)}, got {_describe(value)}')
        unknown = [str(key) for key in value if key not in keys]
        if unknown:
            raise self.fail(path, f'unknown key {", ".join(map(repr, unknown))} (expected: {", ".join(keys)})')
        return value

    def section(self, top: Mapping[str, Any], name: str, keys: tuple[str, ...]) -> Mapping[str, Any]:
        """A top-level mapping; absent or empty (`robot:` alone) means all defaults."""
        value = top.get(name)
        return {} if value is None else self.mapping(value, name, keys)

    def each(self, top: Mapping[str, Any], name: str, keys: tuple[str, ...],
             read: Callable[[_FieldReader, Mapping[str, Any], str], Any]) -> list[Any]:
        """Build one object per item of the top-level list `name` (absent or empty means none)."""
        items = top.get(name)
        if items is None:
            return []
        if not isinstance(items, list):
            raise self.fail(name, f'expected a list, got {_describe(items)}')
        return [read(self, self.mapping(item, f'{name}[{i}]', keys), f'{name}[{i}]') for i, item in enumerate(items)]

    def required(self, item: Mapping[str, Any], key: str, path: str) -> Any:
        if key not in item:
            raise self.fail(f'{path}.{key}', 'missing')
        return item[key]

    def number(self, value: Any, path: str, positive: bool = False) -> float:
        """A finite float within +-MAX_MAGNITUDE (checked before converting: a 400-digit integer overflows float)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f'expected a number, got {_describe(value)}')
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(path, f'must be finite, got {value}')
        if not -MAX_MAGNITUDE <= value <= MAX_MAGNITUDE:
            raise self.fail(path, f'must be within +-{MAX_MAGNITUDE:g}, got {untrusted_yaml.cut(repr(value), 24)}')
        if positive and value <= 0.0:
            raise self.fail(path, f'must be positive, got {value}')
        return float(value)

    def vector(self, value: Any, path: str, length: int, positive: bool = False) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != length:
            raise self.fail(path, f'expected a list of {length} numbers, got {_describe(value)}')
        return tuple(self.number(item, f'{path}[{i}]', positive) for i, item in enumerate(value))


_SHORT_REPR = reprlib.Repr()   # keyword arguments only from Python 3.12
_SHORT_REPR.maxlevel, _SHORT_REPR.maxlist, _SHORT_REPR.maxdict = 2, 4, 4
_SHORT_REPR.maxstring = _SHORT_REPR.maxother = _SHORT_REPR.maxlong = 30


def _describe(value: Any) -> str:
    """Type and a short repr; reprlib stops early, so a huge value is never formatted in full."""
    return f'{type(value).__name__} {untrusted_yaml.cut(_SHORT_REPR.repr(value), 40)}'
