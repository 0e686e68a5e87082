"""The e-puck's infra-red proximity sensors: Webots lookup table forward and inverse, noise, published range.

Rows of the table are (distance m, raw value, relative noise std), distance increasing, raw decreasing
(model.IR_LOOKUP_TABLE). Forward lookups follow Webots: linear interpolation, distances beyond the table take
the end row. The inverse follows webots_ros2 (Math.cpp interpolateLookupTable): piecewise linear, extrapolated
linearly from the two end rows, so raw 60 -> 0.0720 m and raw 0 -> 0.0882 m.

What the model leaves out, on purpose: the ray does not see the robot's own body, the obstacle's colour
(Webots' reflection factor) is taken as 1, and the ray's 0.16 rad upward tilt is ignored (distances are
measured in the floor plane, 1.3 % shorter than Webots' slant distance).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def raw_from_distance(distance: ArrayLike, table: np.ndarray) -> np.ndarray:
    """Noise-free raw value for an obstacle at `distance` (m); inf (nothing hit) reads as the far end row."""
    return np.interp(distance, table[:, 0], table[:, 1])


def noise_from_distance(distance: ArrayLike, table: np.ndarray) -> np.ndarray:
    """Relative standard deviation of the raw value at `distance` (m), the table's third column."""
    return np.interp(distance, table[:, 0], table[:, 2])


def distance_from_raw(raw: ArrayLike, table: np.ndarray) -> np.ndarray:
    """Distance (m) for a raw value: the inverse table, extrapolated linearly beyond both ends (may leave [0, 0.07])."""
    raws, distances = table[::-1, 1], table[::-1, 0]
    slopes = (distances[1:] - distances[:-1]) / (raws[1:] - raws[:-1])
    segment = np.searchsorted(raws[1:-1], raw, side='right')  # below the 2nd raw: 0; from the last but one: last
    return distances[segment] + (raw - raws[segment]) * slopes[segment]


def noisy_raw(distance: np.ndarray, table: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
    """Raw values as Webots draws them: value * (1 + sigma_rel * N(0, 1)); exact when `rng` is None (noise off)."""
    raw = raw_from_distance(distance, table)
    if rng is None:
        return raw
    return raw * (1.0 + noise_from_distance(distance, table) * rng.standard_normal(np.shape(distance)))


def range_from_raw(raw: np.ndarray, hit: np.ndarray, table: np.ndarray) -> np.ndarray:
    """The published range (m): inf where the ray hit nothing (REP 117), else the inverse table clipped to the table.

    Webots' own driver publishes ~0.07 m for a free sensor; `inf` tells a ROS consumer "nothing there" instead.
    """
    if not hit.any():
        return np.full(np.shape(raw), np.inf)
    distance = np.minimum(np.maximum(distance_from_raw(raw, table), 0.0), table[-1, 0])
    return np.where(hit, distance, np.inf)
