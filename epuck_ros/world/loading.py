"""Reading world files: untrusted YAML checked field by field into a World, or one WorldError naming the field.

World file. Every section is optional (none at all: an empty 1 m x 1 m arena, one robot `epuck` at the origin
facing +x); a box needs position and size (yaw defaults to 0), a cylinder position and radius, a robot a start:

    arena: {size: [1.0, 1.0]}
    boxes: [{position: [x, y], size: [sx, sy], yaw: 0.0}]
    cylinders: [{position: [x, y], radius: r}]
    robots: [{name: epuck0, start: [x, y, yaw]}, {name: epuck1, start: [x, y, yaw]}]
    robot: {start: [x, y, yaw]}      # the one-robot form (named `epuck`); not together with `robots`

A robot may carry devices in its turret slot, as Webots' e-puck does (`turretSlot`): `turret: [GPS, Compass,
InertialUnit]`, each a Webots node type (any case; `inertial_unit` too) taking Webots' default name (`gps`, `compass`,
`inertial unit`), or `{type: GPS, name: my gps}` with a name of its own, unique on the robot.

Colours, heights, floor paint and lights are optional too (`appearance`'s docstring has their keys).

The file is untrusted input: it is read only if it is a regular file under MAX_FILE_BYTES, YAML aliases and deep
nesting are refused before anything is built, and numbers must be finite and within MAX_MAGNITUDE, so a hostile
file costs little and ends in one WorldError line naming the file and field.
"""
from __future__ import annotations

import math
import reprlib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from epuck_ros import untrusted_yaml
from epuck_ros.model import RobotModel
from epuck_ros.spatial import close_pairs
from epuck_ros.untrusted_file import FileProblem, read_bounded
from epuck_ros.world.data import (ONE_ROBOT, ROBOT_NAME, ROBOT_NAME_MAX, TURRET_KINDS, Box, Cylinder, RobotStart,
                                  TurretDevice, World, WorldError, name_problem)
from epuck_ros.world import appearance
from epuck_ros.world.geometry import CONTACT_TOLERANCE

MAX_FILE_BYTES = 8 * 2 ** 20
"""A world file larger than this is refused unread (10,000 robots take about 0.6 MB)."""
MAX_NESTING = 16
"""Deepest YAML nesting accepted (the format needs 4); deeper input is refused before it is built."""
MAX_MAGNITUDE = 1e4
"""Largest absolute value (m or rad) of any number in a world: far beyond any arena, far below overflow."""
TURRET_NAME_MAX = 100
"""Characters in a turret device's name at most."""
_TURRET_SPELLINGS = {kind.lower(): kind for kind in TURRET_KINDS}
"""A turret type as a world file may write it, lower case without spaces or underscores: Webots' node type."""


def load_world(path: str | Path, robot_radius: float = RobotModel().body_radius) -> World:
    """Read and check a world YAML file; any problem raises WorldError naming the file and the field.

    The file is opened without blocking and must be a regular file (a named pipe would otherwise hang the
    reader) no larger than MAX_FILE_BYTES.
    """
    try:
        data = read_bounded(path, MAX_FILE_BYTES)
    except FileProblem as problem:
        raise WorldError(f'{path}: {problem}') from None
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
    top = fields.mapping(data, '<top level>', ('arena', 'boxes', 'cylinders', 'robot', 'robots', *appearance.TOP_KEYS))
    arena = fields.section(top, 'arena', ('size', *appearance.ARENA_KEYS))
    if top.get('robot') is not None and top.get('robots') is not None:
        raise fields.fail('robots', 'give either `robots` (a list) or `robot` (one robot), not both')
    if top.get('robots') is not None:
        robots = tuple(fields.each(top, 'robots', ('name', 'start', 'turret'), _read_robot))
        if not robots:
            raise fields.fail('robots', 'the list is empty (leave it out for one robot at the origin)')
    else:
        robot = fields.section(top, 'robot', ('start', 'turret'))
        robots = (RobotStart(ONE_ROBOT[0].name, *fields.vector(robot.get('start', [0.0, 0.0, 0.0]), 'robot.start', 3),
                             _read_turret(fields, robot.get('turret'), 'robot.turret')),)
    problem = name_problem(robots)
    if problem:
        raise fields.fail('robots', problem)
    world = World(arena_size=fields.vector(arena.get('size', [1.0, 1.0]), 'arena.size', 2, positive=True),
                  boxes=tuple(fields.each(top, 'boxes', ('position', 'size', 'yaw', *appearance.OBSTACLE_KEYS),
                                          _read_box)),
                  cylinders=tuple(fields.each(top, 'cylinders', ('position', 'radius', *appearance.OBSTACLE_KEYS),
                                              _read_cylinder)),
                  robots=robots, appearance=appearance.read_appearance(fields, top))
    _check_obstacles_are_inside(world, source)
    _check_robots_are_clear(world, robot_radius, source, 'robots' if 'robots' in top else 'robot')
    return world


def _check_obstacles_are_inside(world: World, source: str) -> None:
    """Every box and cylinder lies on the arena's floor, whole (touching a wall is fine): one outside was accepted
    and silently missing from every picture and every sensor, like a typo nobody is told about."""
    half_x, half_y = world.arena_size[0] / 2.0 + 1e-9, world.arena_size[1] / 2.0 + 1e-9
    for index, box in enumerate(world.boxes):
        if any(abs(x) > half_x or abs(y) > half_y for x, y in box.corners()):
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
                                          f'{describe(name)}')
    if len(name) > ROBOT_NAME_MAX:
        raise fields.fail(f'{path}.name', f'at most {ROBOT_NAME_MAX} characters (its topics must fit in a ROS '
                                          f'topic name), got {len(name)}')
    return RobotStart(name, *fields.vector(fields.required(item, 'start', path), f'{path}.start', 3),
                      _read_turret(fields, item.get('turret'), f'{path}.turret'))


def _read_turret(fields: _FieldReader, value: Any, path: str) -> tuple[TurretDevice, ...]:
    """The devices of a robot's turret slot (absent: none), each a type or {type, name}; names unique."""
    if value is None:
        return ()
    if not isinstance(value, list):
        raise fields.fail(path, f'expected a list of devices ({", ".join(TURRET_KINDS)}), got {describe(value)}')
    devices: list[TurretDevice] = []
    for index, item in enumerate(value):
        where = f'{path}[{index}]'
        if isinstance(item, Mapping):
            item = fields.mapping(item, where, ('type', 'name'))
            kind = _turret_kind(fields, fields.required(item, 'type', where), f'{where}.type')
            name = item.get('name', TURRET_KINDS[kind])
            if not isinstance(name, str) or not name.strip() or not name.isprintable() or len(name) > TURRET_NAME_MAX:
                raise fields.fail(f'{where}.name', f'expected a device name (printable text of 1 to {TURRET_NAME_MAX} '
                                                   f'characters), got {describe(name)}')
        else:
            kind = _turret_kind(fields, item, where)
            name = TURRET_KINDS[kind]
        clash = next((i for i, device in enumerate(devices) if device.name == name), None)
        if clash is not None:
            raise fields.fail(where, f'a second device named {name!r} ({path}[{clash}] has that name): give one of '
                                     f'them a name of its own, e.g. {{type: {kind}, name: {name}2}}')
        devices.append(TurretDevice(kind, name))
    return tuple(devices)


def _turret_kind(fields: _FieldReader, value: Any, path: str) -> str:
    """Webots' node type of a turret device from its spelling in the file (GPS, gps, InertialUnit, inertial_unit)."""
    kind = _TURRET_SPELLINGS.get(value.lower().replace('_', '').replace(' ', '')) if isinstance(value, str) else None
    if kind is None:
        raise fields.fail(path, f'expected a turret device, one of {", ".join(TURRET_KINDS)}, got {describe(value)}')
    return kind


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


class _FieldReader:
    """Typed access to the world file's fields; every failure is a WorldError naming the file and field path."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, path: str, problem: str) -> WorldError:
        return WorldError(f'{self.source}: {path}: {problem}')

    def mapping(self, value: Any, path: str, keys: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(path, f'expected a mapping with keys {", ".join(keys)}, got {describe(value)}')
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
            raise self.fail(name, f'expected a list, got {describe(items)}')
        return [read(self, self.mapping(item, f'{name}[{i}]', keys), f'{name}[{i}]') for i, item in enumerate(items)]

    def required(self, item: Mapping[str, Any], key: str, path: str) -> Any:
        if key not in item:
            raise self.fail(f'{path}.{key}', 'missing')
        return item[key]

    def number(self, value: Any, path: str, positive: bool = False) -> float:
        """A finite float within +-MAX_MAGNITUDE (checked before converting: a 400-digit integer overflows float)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f'expected a number, got {describe(value)}')
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(path, f'must be finite, got {value}')
        if not -MAX_MAGNITUDE <= value <= MAX_MAGNITUDE:
            raise self.fail(path, f'must be within +-{MAX_MAGNITUDE:g}, got {untrusted_yaml.cut(repr(value), 24)}')
        if positive and value <= 0.0:
            raise self.fail(path, f'must be positive, got {value}')
        return float(value)

    def vector(self, value: Any, path: str, length: int, positive: bool = False) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != length:
            raise self.fail(path, f'expected a list of {length} numbers, got {describe(value)}')
        return tuple(self.number(item, f'{path}[{i}]', positive) for i, item in enumerate(value))


_SHORT_REPR = reprlib.Repr()   # keyword arguments only from Python 3.12
_SHORT_REPR.maxlevel, _SHORT_REPR.maxlist, _SHORT_REPR.maxdict = 2, 4, 4
_SHORT_REPR.maxstring = _SHORT_REPR.maxother = _SHORT_REPR.maxlong = 30


def describe(value: Any) -> str:
    """Type and a short repr; reprlib stops early, so a huge value is never formatted in full."""
    return f'{type(value).__name__} {untrusted_yaml.cut(_SHORT_REPR.repr(value), 40)}'
