"""The e-puck's infra-red proximity sensors: Webots lookup table forward and inverse, noise, published range.

Rows of the table are (distance m, raw value, relative noise std), distance increasing, raw decreasing
(model.IR_LOOKUP_TABLE). Forward lookups follow Webots: linear interpolation, distances beyond the table take
the end row. The inverse follows webots_ros2 (Math.cpp interpolateLookupTable): piecewise linear, extrapolated
linearly from the two end rows, so a raw value below the far end's (noise) reads a little beyond the table.

What the model leaves out, on purpose: the ray does not see the robot's own body, the obstacle's colour
(Webots' reflection factor) is taken as 1, and the ray's 0.16 rad upward tilt is ignored (distances are
measured in the floor plane: Webots' slant distance is longer by the factor 1 / cos(0.16), within the
table's noise).
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

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
    return _from_inverse(raw, _inverse(table))


def _inverse(table: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The table's rows by increasing raw value: (raw values, distances, slope of each segment). The IR table's
    values fall with distance, the ToF's (sensors/tof.py) rise: both are read through this inverse."""
    order = np.argsort(table[:, 1], kind='stable')
    raws, distances = table[order, 1], table[order, 0]
    return raws, distances, (distances[1:] - distances[:-1]) / (raws[1:] - raws[:-1])


def _from_inverse(raw: ArrayLike, inverse: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    raws, distances, slopes = inverse
    segment = raws[1:-1].searchsorted(raw, side='right')  # below the 2nd raw: 0; from the last but one: last
    return distances[segment] + (raw - raws[segment]) * slopes[segment]


def noisy_raw(distance: np.ndarray, table: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
    """Raw values as Webots draws them: value * (1 + sigma_rel * N(0, 1)); exact when `rng` is None (noise off)."""
    raw = raw_from_distance(distance, table)
    if rng is None:
        return raw
    return raw * (1.0 + noise_from_distance(distance, table) * rng.standard_normal(np.shape(distance)))


def range_from_raw(raw: np.ndarray, hit: np.ndarray, table: np.ndarray,
                   inverse: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The published range (m): inf where the ray hit nothing (REP 117), else the inverse table clipped to the table.

    Webots' own driver publishes ~0.07 m for a free sensor; `inf` tells a ROS consumer "nothing there" instead.
    `inverse`: the table's inverse computed once (LookupTable), to spare the simulator its NumPy calls every step.
    """
    if not hit.any():
        return np.full(np.shape(raw), np.inf)
    distance = np.minimum(np.maximum(_from_inverse(raw, inverse or _inverse(table)), 0.0), table[-1, 0])
    return np.where(hit, distance, np.inf)


class LookupTable:
    """A table prepared once for the simulator: its inverse for `range_from_raw`, and the table as Python floats for
    `read_one`, one robot's eight readings.

    NumPy's per-call cost dominates on eight values, so `read_one` works on floats. It computes each value with
    the arithmetic np.interp and `distance_from_raw` use, operation for operation (slope * (x - x_j) + y_j, the
    exact row value at a table distance), so the one-robot path reads exactly what the array path reads
    (test_ir_sensor checks).
    """

    def __init__(self, table: np.ndarray) -> None:
        self.table = table
        self.inverse = _inverse(table)
        self._distances, self._raws, self._noises = (table[:, k].tolist() for k in range(3))
        rises = [b - a for a, b in zip(self._distances, self._distances[1:])]
        self._raw_slopes = [(b - a) / d for a, b, d in zip(self._raws, self._raws[1:], rises)]
        self._noise_slopes = [(b - a) / d for a, b, d in zip(self._noises, self._noises[1:], rises)]
        self._inverse_raws, self._inverse_distances, self._inverse_slopes = (a.tolist() for a in self.inverse)
        self._inner_raws = self._inverse_raws[1:-1]
        self._far_raw, self._far_noise, self._far_distance = self._raws[-1], self._noises[-1], self._distances[-1]

    def read_one(self, distances: list[float] | None, normals: list[float] | None,
                 count: int) -> tuple[list[float], list[float]]:
        """(raw values, published ranges) of `count` rays at `distances` (None: every ray hit nothing), with one
        standard normal draw per ray (None: noise off)."""
        far_raw, far_noise, far_distance = self._far_raw, self._far_noise, self._far_distance
        if distances is None:
            raws = [far_raw] * count if normals is None else [far_raw * (1.0 + far_noise * n) for n in normals]
            return raws, [math.inf] * count
        raws, ranges = [], []
        for k, distance in enumerate(distances):
            if distance >= far_distance:   # np.interp: the end rows beyond the table
                raw, noise = far_raw, far_noise
            elif distance < self._distances[0]:
                raw, noise = self._raws[0], self._noises[0]
            else:
                j = bisect.bisect_right(self._distances, distance) - 1
                below = self._distances[j]
                if below == distance:
                    raw, noise = self._raws[j], self._noises[j]
                else:
                    raw = self._raw_slopes[j] * (distance - below) + self._raws[j]
                    noise = self._noise_slopes[j] * (distance - below) + self._noises[j]
            if normals is not None:
                raw = raw * (1.0 + noise * normals[k])
            raws.append(raw)
            ranges.append(self.range_of(raw) if distance < math.inf else math.inf)
        return raws, ranges

    def range_of(self, raw: float) -> float:
        """`range_from_raw` of one raw value that hit something: the inverse table, clipped to the table."""
        segment = bisect.bisect_right(self._inner_raws, raw)
        inverse = self._inverse_distances[segment] + (raw - self._inverse_raws[segment]) * self._inverse_slopes[segment]
        return min(max(inverse, 0.0), self._far_distance)

    def ranges_of(self, raws: Sequence[float], seen_above: float) -> list[float]:
        """`range_from_raw` of raw values that hit something when above `seen_above` (inf for the others), in plain
        floats: a controller reads eight values per step, too few for NumPy to pay its per-call cost."""
        return [self.range_of(raw) if raw > seen_above else math.inf for raw in raws]
