"""Ray casting against the walls and obstacles: NumPy for many rays, plain floats for one robot's eight.

Walls and box edges are segments, cylinders circles (`geometry`). A few rays or obstacles: every ray against
every one. Many: the grid (`cells`) gives each group of rays only the obstacles near it, and only groups near
a wall or obstacle are computed at all, so the cost per ray does not grow with the number of obstacles.
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.world.geometry import Geometry

_ALL_OBSTACLES_UP_TO = 1024
"""Rays x obstacles up to which every ray is tested against every obstacle: cheaper than the grid's lookups."""
_ALL_OBSTACLES_BELOW = 16
"""Fewer obstacles than this: the robots near something test their rays against all of them, no grid lookups."""


def ray_distances(geometry: Geometry, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray,
                  max_range: float, centres: np.ndarray | None = None, spread: float = 0.0) -> np.ndarray:
    """Distance along rays (origins ox, oy and unit directions, each (S, G): S rays in each of G groups, one
    group a column) to the first wall or obstacle; inf beyond max_range. `centres` (G, 2): each group's rays
    start within `spread` of it (a robot's sensors), so obstacles are looked up once per group; without,
    once per ray (the arrays may then have any shape).

    Walls and box edges are segments, cylinders circles, in NumPy over all rays at once. A few rays or
    obstacles: every ray against every one. Many: a grid of cells (see _ObstacleGrid) gives each group only
    the obstacles near it, and only groups near a wall or obstacle are computed at all, so the cost per ray
    does not grow with the number of obstacles. The obstacles are the leading axis and the rays the last
    (contiguous) one: NumPy then runs one long inner loop per obstacle instead of one short loop per ray.
    """
    g = geometry
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
            nearest = _nearest_on_grid(g, ox, oy, dir_x, dir_y, centres, max_range + spread)
    nearest[~(nearest <= max_range)] = np.inf
    return nearest.reshape(shape)


def _nearest_on_grid(geometry: Geometry, ox: np.ndarray, oy: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray,
                     centres: np.ndarray, reach: float) -> np.ndarray:
    """Distance (S, G) along each group's rays to the walls and to the box edges and cylinders (all of them, or
    those the grid lists for the group's cell); only groups the clearance map puts within `reach` of
    something are computed."""
    g = geometry
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


def cast_near(geometry: Geometry, surfaces: list[int], rays: list[tuple[float, float, float, float]],
              max_range: float) -> list[float]:
    """Distance along each ray (origin x, y, unit direction x, y) to the first of the `surfaces`; inf beyond
    max_range. `surfaces` must hold every surface a ray can reach within max_range (`surfaces_near` around
    a point the rays start near, with the reach); one robot's rays, each step.

    Plain floats, with `ray_distances`' formulas operation for operation, so the distances equal its to the
    bit (a test checks): 8 rays against the few surfaces near one robot cost far less on floats than
    `ray_distances` testing every edge in NumPy, whose per-call cost dominates on so few rays. In a
    world so large that `ray_distances` would use its grid, the rays go there.
    """
    g = geometry
    if len(rays) * (g.edge_total + g.cylinder_count) > _ALL_OBSTACLES_UP_TO:
        return ray_distances(g, *np.array(rays).T, max_range).tolist()
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
