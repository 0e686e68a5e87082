"""Which of N points are close to each other: cell lists in NumPy, no Python loop over points.

The simulator asks every few steps which robots can touch or see each other. Testing all N^2 pairs costs 10^8
distance checks at N = 10,000; sorting the points into square cells as wide as the reach and comparing each
point only with its own and the neighbouring cells costs O(N log N). Everything is array code (a sort, two
`searchsorted` calls and a `repeat`), so the cost per point stays flat from 50 to 10,000 points.
"""
from __future__ import annotations

import functools

import numpy as np

_ALL_PAIRS_BELOW = 64
"""Fewer points than this: test all pairs (2,016 at most), which costs less than the grid's dozen NumPy calls."""


def close_pairs(xy: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (i, j), i < j, of every pair of points (N, 2) closer than `reach`, sorted by (i, j).

    The order depends only on which pairs are close, not on how they were found: a caller that keeps a wider
    list for a while (the simulator, see SwarmStepper._cover_pairs) and filters it by distance gets exactly what a
    fresh search would give, so a simulation repeats to the bit however often it searched.
    """
    count = len(xy)
    if count < _ALL_PAIRS_BELOW:
        first, second = _all_pairs(count)   # already in that order
    else:
        first, second = _grid_candidates(xy, reach)
    x, y = xy[:, 0].copy(), xy[:, 1].copy()   # 1-D gathers are several times faster than row gathers
    dx, dy = x[first] - x[second], y[first] - y[second]
    keep = (dx * dx + dy * dy < reach * reach).nonzero()[0]
    first, second = first[keep], second[keep]
    if count >= _ALL_PAIRS_BELOW:
        first, second = np.minimum(first, second), np.maximum(first, second)
        order = np.argsort(first * count + second)   # keys are unique: any sort gives this order
        first, second = first[order], second[order]
    return first, second


@functools.lru_cache(maxsize=_ALL_PAIRS_BELOW)
def _all_pairs(count: int) -> tuple[np.ndarray, np.ndarray]:
    return np.triu_indices(count, 1)


def _grid_candidates(xy: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs in the same or neighbouring cells of side `reach` (a superset of the close pairs), each once.

    Each point looks at the later points of its own cell and at four of its eight neighbour cells (right, and
    the three above); the other four see it in turn, so no pair comes twice.
    """
    count = len(xy)
    cells = np.floor((xy - xy.min(axis=0)) / reach).astype(np.int64)
    width = int(cells[:, 0].max()) + 3
    key = (cells[:, 1] + 1) * width + cells[:, 0] + 1
    order = np.argsort(key, kind='stable')
    sorted_key = key[order]
    points = np.arange(count)
    neighbours = (sorted_key[:, None] + np.array([1, width - 1, width, width + 1])).ravel()
    starts = np.concatenate([points + 1, np.searchsorted(sorted_key, neighbours, 'left')])
    ends = np.concatenate([np.searchsorted(sorted_key, sorted_key, 'right'),
                           np.searchsorted(sorted_key, neighbours, 'right')])
    owners = np.concatenate([points, np.repeat(points, 4)])
    counts = ends - starts
    run_starts = np.cumsum(counts) - counts
    first = np.repeat(owners, counts)
    second = np.repeat(starts - run_starts, counts) + np.arange(int(counts.sum()))
    return order[first], order[second]
