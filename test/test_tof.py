"""The e-puck2's ToF in the core (sensors/tof.py, Senses 'tof') against the closed form: Webots' lookup table of the
distance along its ray, its noise, the Range conversion webots_ros2 makes, and computed only while wanted."""
from __future__ import annotations

import math

import numpy as np
import pytest

from epuck_ros.model import IR_LOOKUP_TABLE, TOF_LOOKUP_TABLE, TOF_POSE, RobotModel
from epuck_ros.sensors import tof
from epuck_ros.simulation import Simulation
from epuck_ros.world import Box, Cylinder, World
from epuck_ros.world.data import RobotStart

X, Y, Z, YAW = TOF_POSE


def along_ray_to_circle(cx: float, cy: float, r: float) -> float:
    """Closed form: where the ToF's ray of a robot at the origin facing +x meets the circle (cx, cy, r)."""
    fx, fy = cx - X, cy - Y
    b = fx * math.cos(YAW) + fy * math.sin(YAW)
    return b - math.sqrt(b * b - (fx * fx + fy * fy - r * r))


def facing_wall(distance: float, noise: bool = False, seed: int = 0) -> Simulation:
    """One robot at the origin facing +x, a box's face `distance` ahead of the ToF's origin along its ray."""
    face = X + distance * math.cos(YAW)
    world = World(arena_size=(6.0, 6.0), boxes=[Box(face + 0.05, 0.0, 0.1, 1.0)], robots=[RobotStart('epuck', 0, 0, 0)])
    return Simulation(world, noise=noise, seed=seed)


@pytest.mark.parametrize('distance', [0.02, 0.05, 0.137, 0.3, 0.5, 0.999, 1.7, 1.95])
def test_a_wall_ahead_reads_the_table_at_its_distance(distance):
    sim = facing_wall(distance)
    sim.senses.want('tof', [0])
    along_ray = distance   # the face is perpendicular to x: the ray meets it distance / cos(yaw) * cos(yaw) ahead
    expected = float(np.interp(along_ray, TOF_LOOKUP_TABLE[:, 0], TOF_LOOKUP_TABLE[:, 1]))
    assert sim.senses.tof[0] == pytest.approx(expected, rel=1e-6)
    assert float(tof.range_from_value(sim.senses.tof[0])) == pytest.approx(distance, abs=1e-6)


def test_nothing_within_two_metres_reads_the_last_row():
    sim = facing_wall(2.3)
    sim.senses.want('tof', [0])
    assert sim.senses.tof[0] == 2000.0
    assert float(tof.range_from_value(2000.0)) == 2.0


def test_another_robot_ahead_is_seen_by_its_body():
    world = World(arena_size=(6.0, 6.0), robots=[RobotStart('a', 0.0, 0.0, 0.0), RobotStart('b', 1.2, 0.0, 0.0)])
    sim = Simulation(world, noise=False)
    sim.senses.want('tof', [0])
    t = along_ray_to_circle(1.2, 0.0, RobotModel().body_radius)
    assert float(tof.range_from_value(sim.senses.tof[0])) == pytest.approx(t, abs=1e-9)
    assert math.isnan(sim.senses.tof[1])   # b does not want it


def test_a_cylinder_ahead_in_the_world():
    world = World(arena_size=(6.0, 6.0), cylinders=[Cylinder(0.8, Y, 0.1)], robots=[RobotStart('epuck', 0, 0, 0)])
    sim = Simulation(world, noise=False)
    sim.senses.want('tof', [0])
    expected = along_ray_to_circle(0.8, Y, 0.1)
    assert float(tof.range_from_value(sim.senses.tof[0])) == pytest.approx(expected, abs=1e-9)


def test_only_computed_while_wanted():
    sim = facing_wall(0.3)
    sim.step()
    assert math.isnan(sim.senses.tof[0]) and not sim.senses.active
    sim.senses.want('tof', [0])
    sim.step()
    assert sim.senses.tof[0] == pytest.approx(323.2333, abs=1e-3)
    sim.senses.want('tof', [0], False)
    assert not sim.senses.active


def test_noise_is_the_tables_relative_deviation():
    sim = facing_wall(0.05, noise=True, seed=3)   # the row 0.05 m: 58.5, relative noise 0.032
    sim.senses.want('tof', [0])
    values = []
    for _ in range(3000):
        sim.step()
        values.append(float(sim.senses.tof[0]))
    values = np.array(values)
    assert values.mean() == pytest.approx(58.5, rel=0.004)
    assert values.std() / 58.5 == pytest.approx(0.032, rel=0.06)


def test_noise_does_not_depend_on_who_else_reads():
    """A robot's ToF noise is a function of (seed, sense, step, robot): the same whether another robot reads too."""
    world = World(arena_size=(6.0, 6.0), robots=[RobotStart('a', 0.0, 0.0, 0.0), RobotStart('b', 0.0, 1.0, 0.0)])
    alone, both = Simulation(world, seed=5), Simulation(world, seed=5)
    alone.senses.want('tof', [0])
    both.senses.want('tof', [0, 1])
    for _ in range(5):
        alone.step()
        both.step()
        assert alone.senses.tof[0] == both.senses.tof[0]


def test_range_message_limits_as_webots_ros2_sets_them():
    """Ros2DistanceSensor.cpp: min = the near row's distance + its noise x distance, max = the far row's - the same:
    the ToF's 0 and 2 m, the IR sensors' 0 and 0.07 - 0.04897 x 0.07 (reference, computed there)."""
    assert tof.RANGE_LIMITS == (0.0, 2.0)
    assert tof.range_limits(IR_LOOKUP_TABLE) == pytest.approx((0.0, 0.0665721))


def test_range_from_value_is_webots_ros2s_inverse_extrapolated():
    """Math.cpp interpolateLookupTable: piecewise linear inside, the end segments' lines outside (not clipped)."""
    assert tof.range_from_value(np.array([19.8, 58.5, 1000.0, 2000.0])) == pytest.approx(
        [0.0, 0.05, 0.5 + 0.5 * (1000.0 - 531.9) / (1052.0 - 531.9), 2.0])
    assert float(tof.range_from_value(10.0)) == pytest.approx(-0.05 * 9.8 / 38.7)
    assert float(tof.range_from_value(2100.0)) == pytest.approx(2.0 + 0.3 * 100.0 / 219.5)
    values = np.array([5.0, 19.8, 33.3, 111.0, 777.7, 1999.0, 2050.0])
    assert tof.value_from_range(tof.range_from_value(values)) == pytest.approx(values, rel=1e-12)


def test_carried_is_the_float32_round_trip():
    for value in (19.8, 58.5, 323.2333, 1234.567, 2000.0):
        assert tof.carried(value) == pytest.approx(value, rel=1e-6)
    assert tof.carried(2000.0) == 2000.0
