"""The world the e-puck drives in: a walled rectangular arena with boxes and cylinders, read from YAML.

The arena is Webots' RectangleArena: the floor is centred on the origin and its walls stand outside the floor,
so the free area is exactly `arena_size`. Geometry is 2-D (everything is taller than the IR rays). A World
prepares its obstacles once: NumPy arrays for casting all rays in one batch, plain floats for the per-disc
collision queries (see `_Geometry` for why).

World file. Every section is optional (none at all: an empty 1 m x 1 m arena, the robot at the origin facing +x);
a box needs position and size (yaw defaults to 0), a cylinder position and radius:

    arena: {size: [1.0, 1.0]}
    boxes: [{position: [x, y], size: [sx, sy], yaw: 0.0}]
    cylinders: [{position: [x, y], radius: r}]
    robot: {start: [x, y, yaw]}
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from epuck_ros.model import RobotModel

CONTACT_TOLERANCE = 1e-6
"""m; a disc this close to an obstacle touches it (a pushed-out disc sits at exactly its radius)."""

_PUSH_ITERATIONS = 4
"""Push-out passes per step; two obstacles meeting at a corner need more than one."""


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


@dataclass(frozen=True)
class World:
    """Arena, obstacles and the robot's start pose; built once, then queried every step."""

    arena_size: tuple[float, float] = (1.0, 1.0)
    boxes: tuple[Box, ...] = ()
    cylinders: tuple[Cylinder, ...] = ()
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    _geometry: _Geometry = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'arena_size', tuple(float(v) for v in self.arena_size))
        object.__setattr__(self, 'boxes', tuple(self.boxes))
        object.__setattr__(self, 'cylinders', tuple(self.cylinders))
        object.__setattr__(self, 'start_pose', tuple(float(v) for v in self.start_pose))
        object.__setattr__(self, '_geometry', _Geometry(self))

    def cast_rays(self, origins: np.ndarray, yaws: np.ndarray, max_range: float) -> np.ndarray:
        """Distance (K,) from each origin (K, 2) along its yaw (K,) to the first wall or obstacle; inf beyond max_range.

        All rays against all segments (walls and box edges) and circles at once: (K, S) arrays, no Python loop.
        """
        g = self._geometry
        dir_x, dir_y = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
        to_x, to_y = g.seg_x - origins[:, 0:1], g.seg_y - origins[:, 1:2]
        with np.errstate(divide='ignore', invalid='ignore'):  # parallel ray and segment: no hit
            inv_denom = 1.0 / (dir_x * g.edge_y - dir_y * g.edge_x)
            along_ray = (to_x * g.edge_y - to_y * g.edge_x) * inv_denom
            along_edge = (to_x * dir_y - to_y * dir_x) * inv_denom
        along_ray[(along_ray < 0.0) | (along_edge < 0.0) | (along_edge > 1.0)] = np.inf
        nearest = along_ray.min(axis=1)
        if len(g.cyl_x):
            from_x, from_y = origins[:, 0:1] - g.cyl_x, origins[:, 1:2] - g.cyl_y
            half_b = from_x * dir_x + from_y * dir_y
            discriminant = half_b * half_b - (from_x * from_x + from_y * from_y - g.cyl_radius_sq)
            root = -half_b - np.sqrt(np.maximum(discriminant, 0.0))  # the nearer of |o + s d - c| = r
            root[(discriminant < 0.0) | (root < 0.0)] = np.inf
            nearest = np.minimum(nearest, root.min(axis=1))
        nearest[nearest > max_range] = np.inf
        return nearest

    def resolve_collision(self, xy: np.ndarray, radius: float,
                          previous: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each disc (N, 2) moved out of every wall and obstacle it overlaps; (xy (N, 2), contact (N,) bool).

        `previous` (N, 2), the discs' last clear positions, is where a disc goes back to if it cannot be freed.
        """
        moved = [self.push_disc_out(x, y, radius, None if previous is None else tuple(previous[i]))
                 for i, (x, y) in enumerate(np.asarray(xy, dtype=float).tolist())]
        return (np.array([(x, y) for x, y, _ in moved]).reshape(-1, 2),
                np.array([contact for _, _, contact in moved], dtype=bool))

    def push_disc_out(self, x: float, y: float, radius: float,
                      previous: tuple[float, float] | None = None) -> tuple[float, float, bool]:
        """One disc moved out of what it overlaps, along each penetration normal; (x, y, touching).

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

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """Distance (N,) from each point (N, 2) to the nearest wall or obstacle surface (0 inside an obstacle)."""
        return np.array([max(0.0, min(d for _, d, _, _ in self._geometry.surfaces_within(x, y, math.inf)))
                         for x, y in np.asarray(xy, dtype=float).reshape(-1, 2).tolist()])

    def overlapping(self, x: float, y: float, radius: float) -> list[str]:
        """Field paths (`boxes[2]`, `arena.size` for a wall) of everything a disc at (x, y) overlaps."""
        names = (['arena.size'] * 4 + [f'boxes[{i}]' for i in range(len(self.boxes))]
                 + [f'cylinders[{i}]' for i in range(len(self.cylinders))])
        return [names[index] for index, distance, _, _ in self._geometry.surfaces_within(x, y, radius)]

    def to_dict(self) -> dict[str, Any]:
        """The world in the YAML file format, with plain floats (yaml.safe_dump writes it)."""
        return {
            'arena': {'size': list(self.arena_size)},
            'boxes': [{'position': [b.x, b.y], 'size': [b.size_x, b.size_y], 'yaw': b.yaw} for b in self.boxes],
            'cylinders': [{'position': [c.x, c.y], 'radius': c.radius} for c in self.cylinders],
            'robot': {'start': list(self.start_pose)},
        }


class _Geometry:
    """A World's walls and obstacles prepared once: NumPy segment arrays for rays, float tuples for discs.

    Rays are many (8 per robot) and cheap to batch, so they go to NumPy. A disc query is one point against a
    few obstacles, where NumPy's per-call overhead would cost more than the arithmetic: plain floats, with a
    bounding-circle test that skips every obstacle out of reach.
    """

    def __init__(self, world: World) -> None:
        self.half_x, self.half_y = world.arena_size[0] / 2.0, world.arena_size[1] / 2.0
        hx, hy = self.half_x, self.half_y
        polygons = [[(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)]] + [_box_corners(box) for box in world.boxes]
        starts = np.array([corner for polygon in polygons for corner in polygon])
        ends = np.array([corner for polygon in polygons for corner in polygon[1:] + polygon[:1]])
        self.seg_x, self.seg_y = starts[:, 0].copy(), starts[:, 1].copy()
        self.edge_x, self.edge_y = ends[:, 0] - starts[:, 0], ends[:, 1] - starts[:, 1]
        self.cyl_x = np.array([c.x for c in world.cylinders])
        self.cyl_y = np.array([c.y for c in world.cylinders])
        self.cyl_radius_sq = np.array([c.radius ** 2 for c in world.cylinders])
        self.boxes = [(b.x, b.y, math.cos(b.yaw), math.sin(b.yaw), b.size_x / 2, b.size_y / 2,
                       math.hypot(b.size_x, b.size_y) / 2) for b in world.boxes]
        self.cylinders = [(c.x, c.y, c.radius) for c in world.cylinders]

    def surfaces_within(self, x: float, y: float, reach: float) -> list[tuple[int, float, float, float]]:
        """(index, signed distance, normal x, normal y) of each surface closer than `reach` to the point (x, y).

        Indexes run over the walls at -x, -y, +x, +y, then the boxes, then the cylinders. The normal points from
        the surface towards the point; the distance is negative inside an obstacle (the normal then points to
        the nearest way out), so a push of (radius - distance) along the normal frees a disc from that surface.
        """
        found = [(index, gap, nx, ny) for index, (gap, nx, ny) in enumerate((
            (x + self.half_x, 1.0, 0.0), (y + self.half_y, 0.0, 1.0),
            (self.half_x - x, -1.0, 0.0), (self.half_y - y, 0.0, -1.0))) if gap < reach]
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
                 boxes=(Box(-0.3, 0.3, 0.1, 0.1), Box(-0.25, 0.0, 0.1, 0.1, 0.5), Box(-0.3, -0.3, 0.1, 0.1)),
                 start_pose=(0.0, 0.0, 0.0))


def load_world(path: str | Path) -> World:
    """Read and check a world YAML file; any problem raises WorldError naming the file and the field."""
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise WorldError(f'{path}: file not found') from None
    except (OSError, UnicodeDecodeError) as error:
        raise WorldError(f'{path}: cannot read the file: {error}') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise WorldError(f'{path}: not valid YAML: {" ".join(str(error).split())}') from None
    return world_from_dict({} if data is None else data, source=str(path))


def world_from_dict(data: Any, source: str = '<dict>', robot_radius: float = RobotModel().body_radius) -> World:
    """Build a World from the file format (see the module docstring), checking every field and the start pose."""
    fields = _FieldReader(source)
    top = fields.mapping(data, '<top level>', ('arena', 'boxes', 'cylinders', 'robot'))
    arena = fields.section(top, 'arena', ('size',))
    robot = fields.section(top, 'robot', ('start',))
    world = World(arena_size=fields.vector(arena.get('size', [1.0, 1.0]), 'arena.size', 2, positive=True),
                  boxes=tuple(fields.each(top, 'boxes', ('position', 'size', 'yaw'), _read_box)),
                  cylinders=tuple(fields.each(top, 'cylinders', ('position', 'radius'), _read_cylinder)),
                  start_pose=fields.vector(robot.get('start', [0.0, 0.0, 0.0]), 'robot.start', 3))
    _check_start_is_clear(world, robot_radius, source)
    return world


def _read_box(fields: _FieldReader, item: Mapping[str, Any], path: str) -> Box:
    x, y = fields.vector(fields.required(item, 'position', path), f'{path}.position', 2)
    size_x, size_y = fields.vector(fields.required(item, 'size', path), f'{path}.size', 2, positive=True)
    return Box(x, y, size_x, size_y, fields.number(item.get('yaw', 0.0), f'{path}.yaw'))


def _read_cylinder(fields: _FieldReader, item: Mapping[str, Any], path: str) -> Cylinder:
    x, y = fields.vector(fields.required(item, 'position', path), f'{path}.position', 2)
    return Cylinder(x, y, fields.number(fields.required(item, 'radius', path), f'{path}.radius', positive=True))


def _check_start_is_clear(world: World, robot_radius: float, source: str) -> None:
    """The robot must start inside the arena and touching nothing, or the first step would teleport it."""
    x, y, _ = world.start_pose
    overlapping = world.overlapping(x, y, robot_radius)
    where = f'the robot (radius {robot_radius} m) at ({x}, {y})'
    if 'arena.size' in overlapping:
        width, height = world.arena_size
        raise WorldError(f'{source}: robot.start: {where} is not inside the {width} m x {height} m arena '
                         f'(|x| <= {width / 2 - robot_radius:.4g}, |y| <= {height / 2 - robot_radius:.4g})')
    if overlapping:
        raise WorldError(f'{source}: robot.start: {where} overlaps {", ".join(overlapping)}')


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
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f'expected a number, got {_describe(value)}')
        if not math.isfinite(value):
            raise self.fail(path, f'must be finite, got {value}')
        if positive and value <= 0.0:
            raise self.fail(path, f'must be positive, got {value}')
        return float(value)

    def vector(self, value: Any, path: str, length: int, positive: bool = False) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != length:
            raise self.fail(path, f'expected a list of {length} numbers, got {_describe(value)}')
        return tuple(self.number(item, f'{path}[{i}]', positive) for i, item in enumerate(value))


def _describe(value: Any) -> str:
    text = repr(value)
    return f'{type(value).__name__} {text if len(text) <= 40 else text[:37] + "..."}'
