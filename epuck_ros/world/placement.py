"""Robots placed by seed: `count` e-pucks clear of walls, obstacles and each other, for swarms and experiments."""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.model import RobotModel
from epuck_ros.world.data import RobotStart, World, WorldError
from epuck_ros.world.geometry import CONTACT_TOLERANCE
from epuck_ros.world.loading import describe

ROBOT_GAP = 0.01
"""m between the bodies of robots placed by `place_robots`, so none starts touching another."""


def placed_names(count: int) -> tuple[str, ...]:
    """The names of `count` robots placed by `place_robots` (`sim -p robots:=N`), in order."""
    return tuple(f'epuck{i}' for i in range(count))


def place_robots(world: World, count: int, seed: int, model: RobotModel = RobotModel()) -> World:
    """`world` with `count` robots named epuck0.. placed clear of walls, obstacles and each other; seeded.

    Candidate spots are a hexagonal lattice (the densest packing of discs) with ROBOT_GAP between bodies, keeping
    those clear of every wall and obstacle; a seeded draw picks `count` of them, jitters each by at most a
    quarter gap and gives it a random heading. So placement never fails when there is room, the same seed always
    gives the same world, and "more than fit" means more than the lattice holds.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise WorldError(f'robots: the number of robots must be a positive integer, got {describe(count)}')
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
    return world.with_robots(RobotStart(name, x, y, heading)
                             for name, (x, y), heading in zip(placed_names(count), chosen.tolist(), yaw.tolist()))
