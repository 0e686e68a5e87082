"""What a world holds: the arena's size, boxes, cylinders and the robots' starts; the World that queries them.

The arena is Webots' RectangleArena: the floor is centred on the origin and its walls stand outside the floor,
so the free area is exactly `arena_size`. Geometry is 2-D (everything is taller than the IR rays). A World
prepares its obstacles once (`geometry.Geometry`); its query methods hand them to the ray casting
(`raycast`) and collision (`collisions`) modules. Reading and checking world files is `loading`'s job.
"""
from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from epuck_ros import untrusted_yaml
from epuck_ros.world import collisions, raycast
from epuck_ros.world.appearance import Appearance, appearance_dict
from epuck_ros.world.geometry import Geometry
from epuck_ros.world.obstacles import Box, Cylinder


class WorldError(ValueError):
    """A world that cannot be used; the message names the file, the field and what is wrong."""


ROBOT_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*\Z')
"""A robot's name is one ROS name token: its topics and frames live under it (`epuck3/odom`)."""
ROBOT_NAME_MAX = 100
"""Characters in a robot's name at most: its topics (`<name>/camera/camera_info` the longest planned, under the
simulator's namespace) must stay within rmw's 247 characters for a full topic name, or the simulator dies
creating them (a valid 240-character name did)."""


TURRET_KINDS = {'GPS': 'gps', 'Compass': 'compass', 'InertialUnit': 'inertial unit'}
"""The devices a world can put in a robot's turret slot (Webots' E-puck.proto `turretSlot`): each Webots node type and
the name Webots gives it by default (its `name` field's default, the name `robot.getDevice` takes)."""


@dataclass(frozen=True)
class TurretDevice:
    """A device in a robot's turret slot: its Webots node type (a key of TURRET_KINDS) and its device name."""

    kind: str
    name: str

    def to_item(self) -> str | dict[str, str]:
        """As a world file gives it: the type alone when the name is Webots' default."""
        return self.kind if self.name == TURRET_KINDS[self.kind] else {'type': self.kind, 'name': self.name}


@dataclass(frozen=True)
class RobotStart:
    """Where a robot starts, the name its ROS ports live under, and the devices in its turret slot."""

    name: str
    x: float
    y: float
    yaw: float = 0.0
    turret: tuple[TurretDevice, ...] = ()

    @property
    def pose(self) -> tuple[float, float, float]:
        """(x, y, yaw) of the start."""
        return (self.x, self.y, self.yaw)


ONE_ROBOT = (RobotStart('epuck', 0.0, 0.0, 0.0),)
"""The robots of a world that names none: one `epuck` at the origin facing +x."""


@dataclass(frozen=True, init=False)
class World:
    """Arena, obstacles and the robots' start poses; built once, then queried every step."""

    arena_size: tuple[float, float] = (1.0, 1.0)
    boxes: tuple[Box, ...] = ()
    cylinders: tuple[Cylinder, ...] = ()
    robots: tuple[RobotStart, ...] = ONE_ROBOT
    appearance: Appearance = Appearance()
    """Colours, heights, floor paint and lights (what the camera, ground and light sensors see)."""
    geometry: Geometry = field(init=False, repr=False, compare=False)
    """The walls and obstacles prepared for queries (what the raycast and collisions functions take)."""

    def __init__(self, arena_size: Iterable[float] = (1.0, 1.0), boxes: Iterable[Box] = (),
                 cylinders: Iterable[Cylinder] = (), robots: Iterable[RobotStart] = ONE_ROBOT,
                 start_pose: Iterable[float] | None = None, appearance: Appearance = Appearance()) -> None:
        """Check the robots' names; `start_pose` is the one-robot form kept for older callers (named `epuck`)."""
        if start_pose is not None:
            if robots is not ONE_ROBOT:
                raise WorldError('robots: give either robots or start_pose, not both')
            robots = (RobotStart(ONE_ROBOT[0].name, *start_pose),)
        object.__setattr__(self, 'arena_size', tuple(float(v) for v in arena_size))
        object.__setattr__(self, 'boxes', tuple(boxes))
        object.__setattr__(self, 'cylinders', tuple(cylinders))
        robots = tuple(RobotStart(str(r.name), float(r.x), float(r.y), float(r.yaw), tuple(r.turret)) for r in robots)
        object.__setattr__(self, 'robots', robots)
        object.__setattr__(self, 'appearance', appearance)
        problem = name_problem(robots)
        if problem:
            raise WorldError(f'robots: {problem}')
        object.__setattr__(self, 'geometry', Geometry(self.arena_size, self.boxes, self.cylinders))

    @property
    def start_pose(self) -> tuple[float, float, float]:
        """The first robot's start pose (the one-robot API)."""
        return self.robots[0].pose

    @property
    def names(self) -> tuple[str, ...]:
        """The robots' names in order."""
        return tuple(robot.name for robot in self.robots)

    def with_robots(self, robots: Iterable[RobotStart]) -> World:
        """The same arena and obstacles with other robots."""
        return World(self.arena_size, self.boxes, self.cylinders, tuple(robots), appearance=self.appearance)

    def cast_rays(self, origins: np.ndarray, yaws: np.ndarray, max_range: float) -> np.ndarray:
        """Distance (K,) from each origin (K, 2) inside the arena along its yaw (K,) to the first wall or obstacle.

        inf beyond max_range.
        """
        yaws = np.asarray(yaws, dtype=float).ravel()
        origins = np.asarray(origins, dtype=float).reshape(-1, 2)
        return self.ray_distances(origins[:, 0], origins[:, 1], np.cos(yaws), np.sin(yaws), max_range)

    def ray_distances(self, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray, max_range: float,
                      centres: np.ndarray | None = None, spread: float = 0.0) -> np.ndarray:
        """Distance along rays to the first wall or obstacle, inf beyond max_range: see `raycast.ray_distances`."""
        return raycast.ray_distances(self.geometry, ox, oy, dir_x, dir_y, max_range, centres, spread)

    def cast_near(self, surfaces: list[int], rays: list[tuple[float, float, float, float]],
                  max_range: float) -> list[float]:
        """One robot's rays against the `surfaces` near it, on floats: see `raycast.cast_near`."""
        return raycast.cast_near(self.geometry, surfaces, rays, max_range)

    def resolve_collision(self, xy: np.ndarray, radius: float,
                          previous: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each disc (N, 2) moved out of what it overlaps; (xy, touching): see `collisions.resolve_collision`."""
        return collisions.resolve_collision(self.geometry, xy, radius, previous)

    def push_disc_out(self, x: float, y: float, radius: float,
                      previous: tuple[float, float] | None = None) -> tuple[float, float, bool]:
        """One disc moved out of what it overlaps; (x, y, touching): see `collisions.push_disc_out`."""
        return collisions.push_disc_out(self.geometry, x, y, radius, previous)

    def anything_within(self, x: float, y: float, distance: float) -> bool:
        """Whether any wall or obstacle surface is closer than `distance` to (x, y); cheap when nothing is."""
        return bool(self.geometry.surfaces_within(x, y, distance))

    def anything_within_each(self, xy: np.ndarray, distance: float) -> np.ndarray:
        """`anything_within` for each point (N, 2): the same answers, the points far from every surface set aside in
        NumPy first (a swarm's tally asks it of every robot at every step)."""
        within = np.zeros(len(xy), dtype=bool)
        for i in np.flatnonzero(self.geometry.maybe_within(xy[:, 0], xy[:, 1], distance)).tolist():
            within[i] = self.anything_within(*xy[i].tolist(), distance)
        return within

    def surfaces_near(self, x: float, y: float, distance: float) -> list[int]:
        """Indexes of the surfaces closer than `distance` to (x, y) (for `cast_near`); empty when nothing is."""
        return self.geometry.surfaces_near(x, y, distance)

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """Distance (N,) from each point (N, 2) to the nearest wall or obstacle surface (0 inside an obstacle)."""
        return collisions.clearance(self.geometry, xy)

    def discs_clear(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """(N,) whether a disc of `radius` at each point (N, 2) is inside the arena and overlaps no obstacle."""
        return collisions.discs_clear(self.geometry, xy, radius)

    def overlapping(self, x: float, y: float, radius: float) -> list[str]:
        """Field paths (`boxes[2]`, `arena.size` for a wall) of everything a disc at (x, y) overlaps."""
        names = (['arena.size'] * 4 + [f'boxes[{i}]' for i in range(len(self.boxes))]
                 + [f'cylinders[{i}]' for i in range(len(self.cylinders))])
        return [names[index] for index, distance, _, _ in self.geometry.surfaces_within(x, y, radius)]

    def to_dict(self) -> dict[str, Any]:
        """The world in the YAML file format, with plain floats (yaml.safe_dump writes it; world_from_dict reads it)."""
        data = {
            'arena': {'size': list(self.arena_size)},
            'boxes': [{'position': [b.x, b.y], 'size': [b.size_x, b.size_y], 'yaw': b.yaw} for b in self.boxes],
            'cylinders': [{'position': [c.x, c.y], 'radius': c.radius} for c in self.cylinders],
        } | self._robots_dict()
        return appearance_dict(self.appearance, data)

    def _robots_dict(self) -> dict[str, Any]:
        """`robot:` for the single default-named robot (what one-robot readers expect), else the `robots:` list; a
        turret only where a robot has one (old readers see the worlds they know)."""
        def turret(robot: RobotStart) -> dict[str, Any]:
            return {'turret': [device.to_item() for device in robot.turret]} if robot.turret else {}

        if self.robots[:1] == self.robots and self.robots[0].name == ONE_ROBOT[0].name:
            return {'robot': {'start': list(self.start_pose), **turret(self.robots[0])}}
        return {'robots': [{'name': r.name, 'start': list(r.pose), **turret(r)} for r in self.robots]}


def name_problem(robots: tuple[RobotStart, ...]) -> str | None:
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


def default_world() -> World:
    """The course's RectangleArena (1 m x 1 m) with three 0.1 m boxes; `worlds/default.yaml` holds the same.

    The boxes stand in the left half, clear of where the course behaviours drive from the origin (the 0.078 m
    circle, the 0.31 m rectangle turning either way, the straight run to the +x wall), and leave an avoiding
    robot gaps of at least 0.1 m everywhere.
    """
    return World(arena_size=(1.0, 1.0),
                 boxes=(Box(-0.3, 0.3, 0.1, 0.1), Box(-0.25, 0.0, 0.1, 0.1, 0.5), Box(-0.3, -0.3, 0.1, 0.1)))
