"""The `epuck_sim` fixture's simulator misused (issue 28, item 19): every misuse is named, before any effect, and the
run's reproducibility is readable (issue 25). A real `sim` process over DDS; nothing here is timed."""
from __future__ import annotations

import math
import subprocess
import time

import pytest
from conftest import BIN_DIR

from epuck_ros.testing.simulator import SimulatorUnderTest

QUIET = 0.5
"""Wall seconds a refused call is given to show an effect (a simulator left running at real_time_factor 0 steps
hundreds of times in that while): a refusal must leave simulated time where it was."""


@pytest.fixture
def sim(tmp_path):
    simulator = SimulatorUnderTest(log_dir=tmp_path)
    yield simulator
    simulator.stop()


def still_paused_at(sim: SimulatorUnderTest, t: float) -> bool:
    time.sleep(QUIET)
    return sim._paused() and sim.time == pytest.approx(t, abs=1e-9)


def test_run_until_refuses_what_it_cannot_do_and_leaves_the_simulation_as_it_was(sim):
    for bad in (math.inf, math.nan, '1.0', True):
        with pytest.raises(ValueError, match='finite number'):
            sim.run_until(bad)
    assert still_paused_at(sim, 0.0)
    reached = sim.run_until(0.5)
    assert reached == pytest.approx(0.512)
    with pytest.raises(ValueError, match='beyond the latest time'):
        sim.run_until(2e9)
    with pytest.raises(ValueError, match='time only runs forward'):
        sim.run_until(0.2)
    assert still_paused_at(sim, reached)
    assert sim.run_until(reached) == reached   # where it is already: nothing to do
    with pytest.raises(KeyError, match='no robot 5: there are 1'):
        sim.ground_truth(5)
    with pytest.raises(KeyError, match="no robot 'epuck9'"):
        sim.contacts('epuck9')


def test_a_stopped_simulator_says_so_at_once(sim):
    sim.stop()
    calls = (lambda: sim.run_until(1.0), sim.contacts, sim.ground_truth, sim.wait_for_controller,
             lambda: sim.reproducible)
    for call in calls:
        began = time.monotonic()
        with pytest.raises(RuntimeError, match='was stopped'):
            call()
        assert time.monotonic() - began < 5.0   # not a wait for a simulator that is gone


MISUSES = [({'robots': '3'}, TypeError), ({'seed': 1.5}, TypeError), ({'robots': -1}, ValueError)]


@pytest.mark.parametrize('arguments, error', MISUSES)
def test_bad_arguments_are_named_before_anything_starts(arguments, error):
    with pytest.raises(error, match=next(iter(arguments))):
        SimulatorUnderTest(**arguments)


def run_with(sim: SimulatorUnderTest, command: list[str], until: float) -> None:
    """`command` as the robot's controller, run to `until`; the controller stopped after."""
    node = subprocess.Popen(command, env=sim.env, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        sim.wait_for_controller()
        sim.run_until(until)
    finally:
        node.terminate()
        node.wait(timeout=30)


def test_a_run_answered_by_name_is_reproducible(sim):
    run_with(sim, [str(BIN_DIR / 'forward'), '--ros-args', '-p', 'use_sim_time:=true'], 1.0)
    assert sim.reproducible and sim.integrity().reason == ''


def test_a_run_driven_by_commands_that_name_no_step_is_not_and_says_why(sim):
    """The teleop node re-sends a plain Twist 20 times a (wall) second: a controller at its own rate."""
    run_with(sim, [str(BIN_DIR / 'teleop'), '--ros-args', '-p', 'repeat_rate:=20.0'], 1.0)
    verdict = sim.integrity()
    assert not sim.reproducible and not verdict.reproducible
    assert verdict.reason.startswith('the controller of epuck sends commands that name no step'), verdict
    assert verdict.since is not None
