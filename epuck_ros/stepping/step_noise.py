"""The senses' noise as a function of (seed, sense, step, robot, channel) alone.

A sense is read when someone wants it: a controller that enabled the device, but also a recorder, a view or an
echo that subscribed at some moment DDS discovery chose, and a sense newly wanted is read at once. Drawn from one
sequential stream per sense, a robot's noise at step k depended on all of that, so a run reading the light sensors
differed with a recorder attached, and over ROS from headless. Here each value is a hash of its coordinates turned
into a Gaussian (SplitMix64's finaliser on a counter, Box–Muller), so it is the same whoever else reads what, and
whenever. Hand-written because NumPy's generators are sequential streams: one Philox per robot and step, positioned
by its counter, gives the same property but costs tens of microseconds a robot (test_step_noise measures neither;
the sense benchmarks in bench_senses show the cost of a step with noise).
"""
from __future__ import annotations

import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1, _MIX2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
_TO_UNIT = 2.0 ** -53


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser: a bijection of uint64 whose outputs look independent for neighbouring inputs."""
    x = (x ^ (x >> np.uint64(30))) * _MIX1
    x = (x ^ (x >> np.uint64(27))) * _MIX2
    return x ^ (x >> np.uint64(31))


class StepNoise:
    """Standard normal draws for the rows (robots) of one sense's reading at one step, each robot's and channel's
    fixed by the coordinates: `standard_normal(shape)`, the one method `sensors.lookup` asks of a generator."""

    def __init__(self, seed: int, stream: int, step: int, rows: np.ndarray) -> None:
        with np.errstate(over='ignore'):
            key = _mix(np.uint64(seed & 0xFFFFFFFFFFFFFFFF) * _GOLDEN + np.uint64(stream))
            key = _mix(key ^ (np.uint64(step) * _GOLDEN))
            self._keys = _mix(key ^ (np.asarray(rows, dtype=np.uint64) * _GOLDEN))

    def standard_normal(self, shape: tuple[int, ...]) -> np.ndarray:
        """(rows, *channels) draws; the same rows and step give the same values, whatever else was drawn."""
        channels = int(np.prod(shape[1:], dtype=np.int64))
        with np.errstate(over='ignore'):
            counters = self._keys[:, None] + np.arange(channels, dtype=np.uint64)[None, :] * (_GOLDEN << np.uint64(1))
            first = _mix(counters)
            second = _mix(counters + _GOLDEN)
        uniform = 1.0 - (first >> np.uint64(11)).astype(np.float64) * _TO_UNIT   # (0, 1]: the log is finite
        angle = (second >> np.uint64(11)).astype(np.float64) * (_TO_UNIT * 2.0 * np.pi)
        return (np.sqrt(-2.0 * np.log(uniform)) * np.cos(angle)).reshape(shape)
