"""Differential-drive formulas, the per-wheel clamp, the exact arc and encoder quantisation."""
import math

import numpy as np
import pytest

from epuck_ros.kinematics import (clamp_wheels, integrate_arc, quantise, twist_from_wheels, wheels_from_twist,
                                  wrap_angle)
from epuck_ros.model import RobotModel

MODEL = RobotModel()


def test_twist_from_wheels_is_the_course_formula():
    v, w = twist_from_wheels(2.0, 5.0, MODEL)
    assert v == pytest.approx(0.020 / 2 * (5.0 + 2.0))
    assert w == pytest.approx(0.020 / 0.052 * (5.0 - 2.0))


def test_wheels_from_twist_inverts_twist_from_wheels_on_arrays():
    left, right = np.array([-3.0, 0.0, 6.28]), np.array([1.5, 0.0, -2.0])
    back_left, back_right = wheels_from_twist(*twist_from_wheels(left, right, MODEL), MODEL)
    np.testing.assert_allclose(back_left, left)
    np.testing.assert_allclose(back_right, right)


def test_each_wheel_is_clamped_on_its_own():
    assert clamp_wheels(10.0, 3.0, 6.28) == (6.28, 3.0)
    assert clamp_wheels(-10.0, -7.0, 6.28) == (-6.28, -6.28)
    left, right = clamp_wheels(np.array([7.0, -1.0]), np.array([0.5, -9.0]), 6.28)
    np.testing.assert_array_equal(left, [6.28, -1.0])
    np.testing.assert_array_equal(right, [0.5, -6.28])


@pytest.mark.parametrize('x, y, yaw, v, w, dt', [
    (0.0, 0.0, 0.0, 0.1, 1.0, 0.032),
    (0.3, -0.2, 2.5, 0.05, -3.0, 0.5),
    (-1.0, 2.0, -3.0, -0.12, 0.7, 2.0),
    (0.0, 0.0, 1.0, 0.1, 4.8, 1.0),   # more than a half turn in one step
])
def test_integrate_arc_matches_the_closed_form(x, y, yaw, v, w, dt):
    new_yaw = yaw + w * dt
    expected_x = x + v / w * (math.sin(new_yaw) - math.sin(yaw))
    expected_y = y - v / w * (math.cos(new_yaw) - math.cos(yaw))
    got_x, got_y, got_yaw = integrate_arc(x, y, yaw, v, w, dt)
    assert (got_x, got_y) == pytest.approx((expected_x, expected_y), abs=1e-12)
    assert math.cos(got_yaw - new_yaw) == pytest.approx(1.0)


def test_integrate_arc_on_arrays_equals_floats():
    rng = np.random.default_rng(3)
    x, y, yaw, v, w = rng.uniform(-1, 1, size=(5, 20))
    w[0] = 0.0
    arrays = integrate_arc(x, y, yaw, v, w, 0.032)
    for i in range(20):
        floats = integrate_arc(float(x[i]), float(y[i]), float(yaw[i]), float(v[i]), float(w[i]), 0.032)
        assert np.array(floats) == pytest.approx(np.array([a[i] for a in arrays]), abs=1e-15)


@pytest.mark.parametrize('w', [0.0, 1e-12, -1e-15, 5e-324])
def test_straight_line_limit_has_no_blow_up(w):
    x, y, yaw = integrate_arc(0.1, 0.2, math.pi / 6, 0.05, w, 2.0)
    assert (x, y) == pytest.approx((0.1 + 0.1 * math.cos(math.pi / 6), 0.2 + 0.1 * math.sin(math.pi / 6)), abs=1e-12)
    assert yaw == pytest.approx(math.pi / 6)


def test_many_short_arcs_compose_into_one_long_arc():
    """Exact for constant speeds: step size does not matter (Euler would drift)."""
    pose = (0.0, 0.0, 0.0)
    for _ in range(1000):
        pose = integrate_arc(*pose, 0.1, 0.9, 0.01)
    assert pose == pytest.approx(integrate_arc(0.0, 0.0, 0.0, 0.1, 0.9, 10.0), abs=1e-12)


def test_yaw_is_wrapped_into_minus_pi_to_pi():
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle(-3 * math.pi / 2) == pytest.approx(math.pi / 2)
    _, _, yaw = integrate_arc(0.0, 0.0, 3.0, 0.0, 1.0, 1.0)
    assert -math.pi <= yaw < math.pi


def test_encoder_reads_the_nearest_multiple_of_its_resolution():
    resolution = MODEL.encoder_resolution
    assert resolution == pytest.approx(2 * math.pi / 1000)
    assert quantise(0.4 * resolution, resolution) == 0.0
    assert quantise(0.6 * resolution, resolution) == pytest.approx(resolution)
    angles = np.linspace(-20.0, 20.0, 10001)
    readings = quantise(angles, resolution)
    assert np.abs(readings - angles).max() <= resolution / 2 + 1e-12
    np.testing.assert_allclose(readings / resolution, np.round(readings / resolution), atol=1e-9)


def test_integrate_arc_takes_array_poses_with_scalar_speeds_and_the_reverse():
    xs, ys, yaws = np.array([0.0, 0.3, -1.0]), np.array([0.0, -0.2, 2.0]), np.array([0.0, 2.5, -3.0])
    each = [integrate_arc(float(x), float(y), float(yaw), 0.1, 1.5, 0.5) for x, y, yaw in zip(xs, ys, yaws)]
    together = integrate_arc(xs, ys, yaws, 0.1, 1.5, 0.5)
    np.testing.assert_allclose(np.array(together).T, each, atol=1e-15)
    speeds, turns = np.array([0.1, -0.05, 0.0]), np.array([0.0, 3.0, -1.0])
    each = [integrate_arc(0.3, -0.2, 2.5, float(v), float(w), 0.5) for v, w in zip(speeds, turns)]
    together = np.broadcast_arrays(*integrate_arc(0.3, -0.2, 2.5, speeds, turns, 0.5))
    np.testing.assert_allclose(np.array(together).T, each, atol=1e-15)


def test_robot_models_compare_and_hash_by_value():
    assert RobotModel() == RobotModel()
    assert hash(RobotModel()) == hash(RobotModel())
    assert RobotModel() != RobotModel(body_radius=0.04)
    assert RobotModel() != RobotModel(ir_table=RobotModel().ir_table * 2.0)
    assert len({RobotModel(), RobotModel()}) == 1
    with pytest.raises(ValueError):
        RobotModel().ir_table[0, 0] = 1.0   # frozen all the way down: the tables are read-only
