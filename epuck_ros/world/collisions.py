"""Discs against the walls and obstacles: pushed out of what they overlap, or asked whether they are clear.

One rule, two implementations: `push_disc_out` on plain floats for one robot, `resolve_collision` in NumPy for
many (a test checks they agree).
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.world.geometry import CONTACT_TOLERANCE, Geometry

_PUSH_ITERATIONS = 4
"""Push-out passes per step; two obstacles meeting at a corner need more than one."""


def resolve_collision(geometry: Geometry, xy: np.ndarray, radius: float,
                      previous: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each disc (N, 2) moved out of every wall and obstacle it overlaps; (xy (N, 2), touching (N,) bool).

    The same rule as `push_disc_out`, for all discs at once in NumPy (the simulator's path for many robots);
    `previous` (N, 2), the discs' last clear positions, is where a disc goes back to if it cannot be freed.
    """
    g = geometry
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


def push_disc_out(geometry: Geometry, x: float, y: float, radius: float,
                  previous: tuple[float, float] | None = None) -> tuple[float, float, bool]:
    """One disc moved out of what it overlaps, along each penetration normal; (x, y, touching).

    Plain floats: for one robot this is several times cheaper than the NumPy `resolve_collision`, which
    follows the same rule (a test checks they agree).

    A disc driven into a wall ends touching it, so it slides along. A few passes settle a disc pushed into
    a corner by two obstacles; if they cannot (a gap narrower than the disc), it goes back to `previous`.
    Touching means closer than CONTACT_TOLERANCE: a pushed-out disc sits at exactly its radius.
    """
    surfaces = geometry.surfaces_within(x, y, radius + CONTACT_TOLERANCE)
    touching = bool(surfaces)
    for _ in range(_PUSH_ITERATIONS):
        overlaps = [(radius - distance, nx, ny) for _, distance, nx, ny in surfaces if distance < radius]
        if not overlaps:
            return x, y, touching
        x += sum(depth * nx for depth, nx, _ in overlaps)
        y += sum(depth * ny for depth, _, ny in overlaps)
        surfaces = geometry.surfaces_within(x, y, radius - CONTACT_TOLERANCE)
    if surfaces and previous is not None:
        x, y = previous
    return x, y, touching


def clearance(geometry: Geometry, xy: np.ndarray) -> np.ndarray:
    """Distance (N,) from each point (N, 2) to the nearest wall or obstacle surface (0 inside an obstacle)."""
    return np.array([max(0.0, min(d for _, d, _, _ in geometry.surfaces_within(x, y, math.inf)))
                     for x, y in np.asarray(xy, dtype=float).reshape(-1, 2).tolist()])


def discs_clear(geometry: Geometry, xy: np.ndarray, radius: float) -> np.ndarray:
    """(N,) whether a disc of `radius` at each point (N, 2) is inside the arena and overlaps no obstacle:
    every point at once, each against the obstacles the grid lists near it."""
    g = geometry
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
