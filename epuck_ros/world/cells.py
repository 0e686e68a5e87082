"""The grids that keep a query's cost flat as a world grows: obstacles per cell, and a clearance raster.

A query from a point tests only the obstacles its cell lists (`ObstacleGrid`), and most points are far from
everything: one lookup in the `ClearanceMap` says so before any per-obstacle work.
"""
from __future__ import annotations

import math
from typing import Protocol

import numpy as np


class Obstacles(Protocol):
    """What the grids read of the prepared walls and obstacles (`geometry.Geometry`, which builds the grids, so
    it is named here by what it offers, not imported)."""

    half_x: float
    half_y: float
    boxes: list[tuple[float, float, float, float, float, float, float]]
    """x, y, cos, sin of yaw, half sizes, bounding radius."""
    cylinders: list[tuple[float, float, float]]
    edge_total: int

    def grid(self, reach: float) -> ObstacleGrid:
        """The obstacle grid for queries that reach `reach`."""

    def surfaces(self, x: np.ndarray, y: np.ndarray, box_ids: np.ndarray,
                 cylinder_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signed distances and outward normals from points to the walls and the listed obstacles."""


class ObstacleGrid:
    """Square cells over the arena, each listing the boxes and cylinders within `reach` of any point in it.

    A query from a point then tests only its cell's few obstacles: the cost per robot or ray stays flat as a
    world grows to thousands of obstacles. Rows are padded with the dummy obstacle (index B or C).
    """

    def __init__(self, geometry: Obstacles, reach: float) -> None:
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


class ClearanceMap:
    """A fine raster over the arena holding, per cell, a lower bound of the distance from any point in it to the
    nearest wall or obstacle (capped at CAP).

    Most robots are far from everything most of the time: one lookup per robot says which ones need no
    collision test and whose rays cannot reach a wall or obstacle, before any per-obstacle work. At most
    about 250,000 cells (5 mm in a 1 m arena, 3 cm in a 15 m one); the bound is the cell centre's distance
    less half the cell's diagonal (distance changes by at most that much within a cell).
    """

    CAP = 0.25
    """m; queries ask about less than this (a robot's sensing reach is about 0.14 m)."""

    def __init__(self, geometry: Obstacles) -> None:
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
