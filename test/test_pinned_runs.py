"""Runs pinned to the bit: a hash of the final state of fixed scenarios, recorded before the core was reshaped.

A refactoring of the world, the simulation or the IR sensor must not change what a seeded run computes. The
hashes below were computed with the code as it stood before the split of world.py and simulation.py (commit
f8b2431); any change to the arithmetic, the order of the random draws or the order of the robot pairs changes
them. A deliberate change of behaviour re-records them (run this file's `_fingerprint` and paste the new value).
They hold for IEEE doubles and the NumPy and libm this package is tested with.
"""
import hashlib

import numpy as np
import pytest

from epuck_ros.simulation import Simulation
from epuck_ros.world import Box, Cylinder, World, default_world, place_robots

CROWDED = World(arena_size=(4.0, 4.0),
                boxes=tuple(Box(-1.8 + 0.45 * i, 1.5 - 0.9 * (i % 4), 0.1, 0.15, 0.3 * i) for i in range(9)),
                cylinders=tuple(Cylinder(-1.7 + 0.4 * i, -1.0 + 0.7 * (i % 3), 0.05) for i in range(9)))
"""Eighteen obstacles: the ray caster uses its grid; with 80 robots the pair search uses its cells too."""


def _fingerprint(world: World, steps: int, noise: bool) -> str:
    """Step `world` with seeded wheel and twist commands, a reset halfway; hash the events and the final arrays."""
    sim = Simulation(world, seed=7, noise=noise)
    rng = np.random.default_rng(8)
    digest = hashlib.sha256()
    for k in range(steps):
        if k % 50 == 0:
            for robot in range(len(world.robots)):
                if k % 100 == 0:
                    sim.command_wheels(robot, *rng.uniform(-7.0, 7.0, 2).tolist())
                else:
                    sim.command_twist(robot, float(rng.uniform(-0.2, 0.2)), float(rng.uniform(-3.0, 3.0)))
        if k == steps // 2:
            sim.reset()
        events = sim.step()
        digest.update(repr((events.new_contacts, events.timed_out)).encode())
    for state in (sim.true_pose, sim.true_twist, sim.odom_pose, sim.odom_twist, sim.wheel_angles, sim.wheel_speeds,
                  sim.ir_raw, sim.ir_range, sim.collisions, sim.robot_collisions, sim.in_contact):
        digest.update(np.ascontiguousarray(state).tobytes())
    return digest.hexdigest()[:16]


@pytest.mark.parametrize('scenario, world, steps, noise, expected', [
    ('one robot, default world, noise', default_world(), 2000, True, '5c283ae085487989'),
    ('one robot, default world, exact', default_world(), 2000, False, '55c666deeb52aac6'),
    ('ten robots, default world, noise', place_robots(default_world(), 10, seed=3), 1000, True, 'd2db9def1b058e6b'),
    ('one robot, crowded world', CROWDED, 1000, True, 'e6c37d22ee2d3eaa'),
    ('eighty robots, crowded world', place_robots(CROWDED, 80, seed=3), 300, True, '368c7594934c7c85'),
])
def test_seeded_run_is_the_recorded_one(scenario, world, steps, noise, expected):
    assert _fingerprint(world, steps, noise) == expected, scenario
