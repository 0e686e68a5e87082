"""The Simulation: course motions, clamping, timeout, reset, encoders and odometry, sensors, collisions."""
import math

import numpy as np
import pytest

from epuck_ros.bag.shapes import fit_circle
from epuck_ros.ir_sensor import raw_from_distance
from epuck_ros.model import IR_LOOKUP_TABLE, MAX_WHEEL_SPEED, SENSOR_POSES, RobotModel
from epuck_ros.simulation import CommandError, Simulation
from epuck_ros.world import Box, Cylinder, RobotStart, World

MODEL = RobotModel()
RADIUS = MODEL.body_radius


def at(pose) -> tuple[RobotStart, ...]:
    """One robot, named as in a one-robot world file, starting at `pose`."""
    return (RobotStart('epuck', *pose),)


def open_floor(start=(0.0, 0.0, 0.0), **kwargs) -> Simulation:
    """A robot on a 4 m x 4 m floor: nothing in reach of the motions below."""
    options = dict(noise=False, cmd_timeout=0.0) | kwargs
    return Simulation(World(arena_size=(4.0, 4.0), robots=at(start)), **options)


def run(sim: Simulation, seconds: float) -> list[np.ndarray]:
    """Step for `seconds` and return the true pose after each step."""
    poses = []
    for _ in range(round(seconds / sim.time_step)):
        sim.step()
        poses.append(sim.true_pose[0].copy())
    return poses


# --- the course's motions ----------------------------------------------------------------------------------

def test_forward_covers_v_times_t():
    sim = open_floor()
    sim.command_wheels(0, 0.5 * MAX_WHEEL_SPEED, 0.5 * MAX_WHEEL_SPEED)
    run(sim, 3.2)
    v = 0.5 * MAX_WHEEL_SPEED * MODEL.wheel_radius
    assert sim.true_pose[0] == pytest.approx([v * 3.2, 0.0, 0.0], abs=1e-12)
    assert sim.true_twist[0] == pytest.approx([v, 0.0])
    assert sim.odom_pose[0] == pytest.approx([v * 3.2, 0.0, 0.0], abs=MODEL.encoder_resolution * MODEL.wheel_radius)


def test_spin_in_place_has_no_drift_and_turns_at_r_over_l_times_the_difference():
    sim = open_floor(start=(0.5, -0.3, 0.2))
    sim.command_wheels(0, 0.5 * MAX_WHEEL_SPEED, -0.5 * MAX_WHEEL_SPEED)
    poses = np.array(run(sim, 2.0))
    w = MODEL.wheel_radius / MODEL.wheel_separation * (-0.5 - 0.5) * MAX_WHEEL_SPEED
    np.testing.assert_allclose(poses[:, :2], np.tile([0.5, -0.3], (len(poses), 1)), atol=1e-12)
    assert sim.true_twist[0] == pytest.approx([0.0, w])
    turned = np.unwrap(np.concatenate([[0.2], poses[:, 2]]))[-1] - 0.2
    assert turned == pytest.approx(w * sim.time)


def test_circle_has_the_course_radius():
    sim = open_floor()
    sim.command_wheels(0, 0.3 * MAX_WHEEL_SPEED, 0.6 * MAX_WHEEL_SPEED)
    xy = np.array(run(sim, 10.0))[:, :2]
    radius, (a, b), _ = fit_circle(xy[:, 0], xy[:, 1])
    assert radius == pytest.approx(0.078, abs=1e-9)
    assert (a, b) == pytest.approx((0.0, 0.078), abs=1e-9)


def test_each_wheel_is_clamped_on_its_own():
    sim = open_floor()
    sim.command_wheels(0, 10.0, 3.0)
    sim.step()
    assert sim.wheel_speeds[0] == pytest.approx([MAX_WHEEL_SPEED, 3.0])
    sim.command_twist(0, 1.0, 0.0)   # 50 rad/s asked of both wheels
    sim.step()
    assert sim.wheel_speeds[0] == pytest.approx([MAX_WHEEL_SPEED, MAX_WHEEL_SPEED])
    sim.command_twist(0, 0.1, 10.0)   # curvature changes under saturation, as in Webots
    sim.step()
    assert sim.wheel_speeds[0] == pytest.approx([-MAX_WHEEL_SPEED, MAX_WHEEL_SPEED])


def test_twist_command_turns_into_wheel_speeds():
    sim = open_floor()
    sim.command_twist(0, 0.05, 0.5)
    sim.step()
    assert sim.wheel_speeds[0] == pytest.approx([(0.05 - 0.013) / 0.02, (0.05 + 0.013) / 0.02])
    assert sim.true_twist[0] == pytest.approx([0.05, 0.5])


# --- commands: errors, timeout, reset -------------------------------------------------------------------

@pytest.mark.parametrize('command, args', [
    ('command_wheels', (math.nan, 1.0)), ('command_wheels', (1.0, math.inf)), ('command_twist', (-math.inf, 0.0)),
    ('command_twist', (0.0, math.nan)), ('command_wheels', ('fast', 1.0)),
])
def test_non_finite_commands_are_refused_and_change_nothing(command, args):
    sim = open_floor()
    sim.command_wheels(0, 1.0, 2.0)
    with pytest.raises(CommandError, match='command rejected'):
        getattr(sim, command)(0, *args)
    sim.step()
    assert sim.wheel_speeds[0] == pytest.approx([1.0, 2.0])


@pytest.mark.parametrize('v, w, wheels', [
    (1e308, 0.0, [MAX_WHEEL_SPEED, MAX_WHEEL_SPEED]),          # the conversion overflows to inf: clamped
    (-1.7e308, 0.0, [-MAX_WHEEL_SPEED, -MAX_WHEEL_SPEED]),
    (0.0, 1e308, [-MAX_WHEEL_SPEED, MAX_WHEEL_SPEED]),
    (1.0, -1e308, [MAX_WHEEL_SPEED, -MAX_WHEEL_SPEED]),
])
def test_huge_finite_twists_clamp_like_wheel_commands(v, w, wheels):
    sim = open_floor()
    sim.command_twist(0, v, w)
    sim.step()
    assert sim.wheel_speeds[0].tolist() == wheels
    assert np.isfinite(sim.true_pose).all()


def test_commanding_every_robot_at_once_is_commanding_each_row():
    """`command_all_wheels` leaves the same bits as `command_wheels` row by row (clamped per wheel) and refuses a
    NaN row or a wrong shape without changing anything."""
    world = World(robots=tuple(RobotStart(f'r{i}', -0.3 + 0.15 * i, 0.0) for i in range(4)))
    speeds = np.array([[1.0, 2.0], [9.0, -9.0], [-0.5, 6.28], [3.3, 3.3]])
    one_by_one, at_once = Simulation(world, seed=2), Simulation(world, seed=2)
    for _ in range(40):
        for i, (left, right) in enumerate(speeds.tolist()):
            one_by_one.command_wheels(i, left, right)
        at_once.command_all_wheels(speeds)
        one_by_one.step()
        at_once.step()
    assert np.array_equal(one_by_one.true_pose, at_once.true_pose)
    assert np.array_equal(at_once.wheel_speeds[1], [MAX_WHEEL_SPEED, -MAX_WHEEL_SPEED])
    before = at_once.wheel_speeds.copy()
    with pytest.raises(CommandError, match=r'rows \[2\]'):
        at_once.command_all_wheels(np.where(np.arange(8).reshape(4, 2) == 5, math.nan, 1.0))
    with pytest.raises(CommandError, match='shape'):
        at_once.command_all_wheels(np.ones((3, 2)))
    at_once.step()
    assert np.array_equal(at_once.wheel_speeds, before)


def test_wheels_stop_when_commands_stop_arriving():
    sim = open_floor(cmd_timeout=0.5)
    sim.command_wheels(0, 2.0, 2.0)
    timed_out, moving = [], []
    for _ in range(40):
        events = sim.step()
        timed_out += [sim.time] * len(events.timed_out)
        moving.append(sim.wheel_speeds[0, 0] != 0.0)
    assert timed_out == [pytest.approx(0.544)]   # the first step that starts more than 0.5 s after the command
    assert moving == [True] * 16 + [False] * 24
    sim.command_wheels(0, 1.0, 1.0)
    sim.step()
    assert sim.wheel_speeds[0] == pytest.approx([1.0, 1.0])


def test_zero_timeout_never_stops():
    sim = open_floor(cmd_timeout=0.0)
    sim.command_wheels(0, 1.0, 1.0)
    run(sim, 5.0)
    assert sim.wheel_speeds[0] == pytest.approx([1.0, 1.0])


def test_reset_returns_to_start_and_zeroes_odometry_but_time_goes_on():
    sim = open_floor(start=(0.2, 0.1, 1.0))
    sim.command_wheels(0, 3.0, 2.0)
    run(sim, 1.0)
    time_before = sim.time
    sim.reset()
    assert sim.time == time_before
    assert sim.true_pose[0] == pytest.approx([0.2, 0.1, 1.0])
    for state in (sim.odom_pose, sim.odom_twist, sim.wheel_angles, sim.wheel_speeds):
        assert not state.any()
    sim.step()
    assert sim.true_pose[0] == pytest.approx([0.2, 0.1, 1.0])
    assert sim.time == pytest.approx(time_before + sim.time_step)


# --- encoders and odometry ---------------------------------------------------------------------------------

def test_wheel_angles_are_encoder_quantised_and_odometry_follows_them():
    sim = open_floor()
    sim.command_wheels(0, 1.2345, -0.987)
    run(sim, 1.0)
    steps = sim.wheel_angles[0] / MODEL.encoder_resolution
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert sim.wheel_angles[0] == pytest.approx([1.2345 * sim.time, -0.987 * sim.time],
                                                abs=MODEL.encoder_resolution / 2)
    v, w = MODEL.wheel_radius / 2 * (1.2345 - 0.987), MODEL.wheel_radius / MODEL.wheel_separation * (-0.987 - 1.2345)
    speed_quantum = MODEL.encoder_resolution / sim.time_step
    assert sim.odom_twist[0] == pytest.approx([v, w], abs=speed_quantum)


# --- sensors -----------------------------------------------------------------------------------------------

def facing_wall(gap: float) -> Simulation:
    """A robot turned so that ps0's ray meets the +x wall square on, `gap` metres from the sensor."""
    yaw = -SENSOR_POSES[0, 2]
    sensor_x = math.cos(yaw) * SENSOR_POSES[0, 0] - math.sin(yaw) * SENSOR_POSES[0, 1]
    sensor_y = math.sin(yaw) * SENSOR_POSES[0, 0] + math.cos(yaw) * SENSOR_POSES[0, 1]
    return Simulation(World(robots=at((0.5 - gap - sensor_x, -sensor_y, yaw))), noise=False)


@pytest.mark.parametrize('gap', [0.01, 0.015, 0.02, 0.03, 0.045, 0.06, 0.0699])
def test_a_sensor_facing_a_wall_reads_the_table(gap):
    sim = facing_wall(gap)
    assert sim.ir_raw[0, 0] == pytest.approx(raw_from_distance(gap, IR_LOOKUP_TABLE))
    assert sim.ir_range[0, 0] == pytest.approx(gap)


@pytest.mark.parametrize('gap', [0.0701, 0.1, 0.3])
def test_a_sensor_with_nothing_within_7_cm_reads_inf(gap):
    sim = facing_wall(gap)
    assert sim.ir_range[0, 0] == math.inf
    assert sim.ir_raw[0, 0] == pytest.approx(IR_LOOKUP_TABLE[-1, 1])


def test_the_sensors_see_what_is_around_the_robot():
    sim = Simulation(World(boxes=[Box(0.0, 0.1, 0.3, 0.1)], robots=at((0.0, 0.0, 0.0))), noise=False)
    seen = np.isfinite(sim.ir_range[0])
    assert seen.tolist() == [False, False, False, False, False, True, True, False]   # the box is on the left
    assert sim.ir_range[0, 5] == pytest.approx(0.05 - 0.031)


def raw_readings(sim: Simulation, steps: int) -> np.ndarray:
    readings = []
    for _ in range(steps):
        sim.step()
        readings.append(sim.ir_raw[0].copy())
    return np.array(readings)


def test_noise_is_seeded():
    world = facing_wall(0.03).world
    first = raw_readings(Simulation(world, seed=5), 20)
    np.testing.assert_array_equal(first, raw_readings(Simulation(world, seed=5), 20))
    assert not np.array_equal(first, raw_readings(Simulation(world, seed=6), 20))


def test_noise_off_is_exact_and_noise_on_scatters_by_the_table_sigma():
    assert raw_readings(facing_wall(0.03), 5)[:, 0] == pytest.approx([234.93] * 5)
    samples = raw_readings(Simulation(facing_wall(0.03).world, seed=1, cmd_timeout=0.0), 3000)[:, 0]
    assert samples.std() / samples.mean() == pytest.approx(0.0241, rel=0.1)
    assert samples.mean() == pytest.approx(234.93, rel=0.005)


# --- collisions --------------------------------------------------------------------------------------------

OBSTACLES = {   # the robot starts at the origin heading +x; the last two push it aside and it slides off
    'wall': World(),
    'box': World(arena_size=(4.0, 4.0), boxes=[Box(0.3, 0.0, 0.1, 0.1)]),
    'rotated box': World(arena_size=(4.0, 4.0), boxes=[Box(0.3, 0.02, 0.1, 0.1, 0.6)]),
    'cylinder': World(arena_size=(4.0, 4.0), cylinders=[Cylinder(0.25, 0.01, 0.02)]),
}


@pytest.mark.parametrize('name', OBSTACLES)
def test_driving_into_an_obstacle_never_penetrates_and_counts_one_collision(name):
    world = OBSTACLES[name]
    sim = Simulation(world, noise=False, cmd_timeout=0.0)
    sim.command_wheels(0, MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)
    clearances, contacts = [], 0
    for _ in range(300):
        contacts += len(sim.step().new_contacts)
        clearances.append(world.clearance(sim.true_pose[:, :2])[0])
    assert min(clearances) >= RADIUS - 1e-9
    assert contacts == 1
    assert sim.collisions[0] == 1


def test_a_blocked_robot_stays_put_while_its_wheels_and_odometry_keep_going():
    sim = Simulation(World(robots=at((0.4, 0.0, 0.0))), noise=False, cmd_timeout=0.0)
    sim.command_wheels(0, MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)
    run(sim, 5.0)
    assert sim.true_pose[0] == pytest.approx([0.5 - RADIUS, 0.0, 0.0])
    assert sim.in_contact[0]
    assert sim.true_twist[0] == pytest.approx([0.0, 0.0])
    v = MAX_WHEEL_SPEED * MODEL.wheel_radius
    assert sim.odom_twist[0, 0] == pytest.approx(v, abs=MODEL.encoder_resolution / sim.time_step)
    assert sim.odom_pose[0, 0] == pytest.approx(v * sim.time, abs=1e-3)   # the odometry believes it drove on
    assert sim.wheel_angles[0] == pytest.approx([MAX_WHEEL_SPEED * sim.time] * 2, abs=MODEL.encoder_resolution)


def test_a_robot_hitting_a_wall_at_an_angle_slides_along_it():
    sim = Simulation(World(robots=at((0.4, 0.0, math.pi / 4))), noise=False, cmd_timeout=0.0)
    sim.command_wheels(0, MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)
    run(sim, 3.0)
    x, y, _ = sim.true_pose[0]
    assert x == pytest.approx(0.5 - RADIUS)
    assert y > 0.2
    assert 0.0 < sim.true_twist[0, 0] < MAX_WHEEL_SPEED * MODEL.wheel_radius


def test_each_contact_is_counted_once_when_it_begins():
    sim = Simulation(World(robots=at((0.3, 0.0, 0.0))), noise=False, cmd_timeout=0.0)
    new_contacts = []
    for forward in (True, False, True, False, True):
        speed = MAX_WHEEL_SPEED if forward else -MAX_WHEEL_SPEED
        sim.command_wheels(0, speed, speed)
        for _ in range(100):
            new_contacts += sim.step().new_contacts
        assert sim.in_contact[0] == forward
    assert new_contacts == [0, 0, 0]
    assert sim.collisions[0] == 3


def test_driving_into_an_arena_corner_stays_inside():
    sim = Simulation(World(robots=at((0.3, 0.3, math.pi / 4 + 0.1))), noise=False, cmd_timeout=0.0)
    sim.command_wheels(0, MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)
    run(sim, 5.0)
    assert sim.true_pose[0, :2] == pytest.approx([0.5 - RADIUS, 0.5 - RADIUS])
    assert sim.collisions[0] == 1


def test_a_long_time_step_does_not_tunnel_through_a_thin_obstacle():
    world = World(arena_size=(4.0, 4.0), boxes=[Box(0.5, 0.0, 0.01, 0.5)])
    sim = Simulation(world, time_step=1.0, noise=False, cmd_timeout=0.0)
    sim.command_wheels(0, MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)   # 12.6 cm per step
    run(sim, 10.0)
    assert sim.true_pose[0, 0] == pytest.approx(0.495 - RADIUS)
