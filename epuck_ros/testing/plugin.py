"""pytest plugin (entry point `pytest11`: `epuck_ros`): the `epuck_sim` fixture for testing ROS nodes against the
simulator in CI.

    def test_my_node(epuck_sim):
        sim = epuck_sim(world=None, robots=0, seed=0)     # lockstep, paused, on a private ROS domain
        node = subprocess.Popen(['my_node'], env=sim.env)  # the test's own process joins that domain
        sim.wait_for_controller()
        sim.run_until(5.0)                                # simulated seconds
        assert sim.contacts() == 0

Every simulator the test started is stopped when the test ends, passed or failed. Importing this module costs
nothing: ROS is imported only when a test asks for the fixture.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from epuck_ros.testing.simulator import SimulatorUnderTest


@pytest.fixture
def epuck_sim(tmp_path: Path) -> Iterator[Callable[..., SimulatorUnderTest]]:
    """A factory of simulators: called with world=None, robots=0, seed=0 and more parameters of `sim` (e.g.
    `noise=False`, passed as `-p name:=value`), it starts one; its output is in `sim.log_path`."""
    started: list[SimulatorUnderTest] = []

    def start(world: str | Path | None = None, robots: int = 0, seed: int = 0,
              **parameters: object) -> SimulatorUnderTest:
        sim = SimulatorUnderTest(world, robots, seed, log_dir=tmp_path, **parameters)
        started.append(sim)
        return sim

    try:
        yield start
    finally:
        for sim in reversed(started):
            sim.stop()
