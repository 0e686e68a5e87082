"""Webots' lookup table for any sensor: input -> value by linear interpolation (the end rows beyond the table),
plus Gaussian noise whose standard deviation is the table's third column times the value (reference manual,
DistanceSensor, "Lookup Table"). Each sensor kind draws from its own stream, so turning one on never changes
another's readings."""
from __future__ import annotations

import numpy as np

STREAMS = {'ground': 1, 'light': 2, 'accelerometer': 3, 'gyro': 4, 'tof': 5}
"""Each sensor kind's noise stream: numpy's default_rng([seed, stream]); the IR sensors keep default_rng(seed)."""


def sensor_rng(seed: int, kind: str) -> np.random.Generator:
    return np.random.default_rng([int(seed), STREAMS[kind]])


def lookup(inputs: np.ndarray, table: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
    """Values of `inputs` (any shape) through `table` (rows: input increasing, value, relative noise); exact when
    `rng` is None."""
    value = np.interp(inputs, table[:, 0], table[:, 1])
    if rng is None:
        return value
    return value * (1.0 + np.interp(inputs, table[:, 0], table[:, 2]) * rng.standard_normal(np.shape(inputs)))
