"""Several robots in one Simulation: contacts between robots, seeing each other, per-robot commands and timeouts,
placement, determinism, and the many-robot path agreeing with the one-robot path."""
import math

import numpy as np
import pytest

from epuck_ros.ir_sensor import raw_from_distance
from epuck_ros.model import IR_LOOKUP_TABLE, MAX_WHEEL_SPEED, SENSOR_POSES, RobotModel
from epuck_ros.simulation import CommandError, Simulation
from epuck_ros.stepping.swarm import SwarmStepper
from epuck_ros.spatial import close_pairs
from epuck_ros.world import Box, Cylinder, RobotStart, World, WorldError, default_world, place_robots, world_from_dict

MODEL = RobotModel()
RADIUS = MODEL.body_radius
DIAMETER = 2 * RADIUS
FULL = MAX_WHEEL_SPEED


def robots(*poses) -> tuple[RobotStart, ...]:
    return tuple(RobotStart(f'r{i}', *pose) for i, pose in enumerate(poses))


def simulation(*poses, arena=(2.0, 2.0), boxes=(), cylinders=(), **options) -> Simulation:
    world = World(arena_size=arena, boxes=boxes, cylinders=cylinders, robots=robots(*poses))
    return Simulation(world, **(dict(noise=False, cmd_timeout=0.0) | options))


def centre_distances(sim: Simulation) -> np.ndarray:
    """Distances between the centres of all pairs of robots."""
    xy = sim.true_pose[:, :2]
    first, second = np.triu_indices(len(xy), 1)
    return np.hypot(*(xy[first] - xy[second]).T)


def run_checked(sim: Simulation, steps: int) -> list[list[int]]:
    """Step, checking after every step that no two bodies overlap and none is in a wall or obstacle."""
    contacts = []
    for _ in range(steps):
        contacts.append(sim.step().new_contacts)
        assert centre_distances(sim).min(initial=math.inf) >= DIAMETER - 1e-9
        assert sim.world.clearance(sim.true_pose[:, :2]).min() >= RADIUS - 1e-9
    return contacts


# --- robots collide with each other ------------------------------------------------------------------------

def test_head_on_robots_stop_touching_and_each_counts_one_robot_contact():
    sim = simulation((-0.2, 0.0, 0.0), (0.2, 0.0, math.pi))
    for robot in (0, 1):
        sim.command_wheels(robot, FULL, FULL)
    contacts = run_checked(sim, 200)
    assert sim.true_pose[:, 0] == pytest.approx([-RADIUS, RADIUS], abs=1e-6)   # met in the middle, blocked
    assert sim.true_twist[:, 0] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert [c for c in contacts if c] == [[0, 1]]
    assert sim.collisions.tolist() == [1, 1]
    assert sim.robot_collisions.tolist() == [1, 1]
    assert sim.in_contact.tolist() == [True, True]


def test_a_glancing_contact_deflects_both_and_nobody_passes_through():
    sim = simulation((-0.3, 0.0, 0.0), (0.3, 0.05, math.pi))   # 5 cm apart sideways: closer than a diameter
    for robot in (0, 1):
        sim.command_wheels(robot, FULL, FULL)
    run_checked(sim, 300)
    assert sim.robot_collisions.tolist() == [1, 1]
    x0, y0, _ = sim.true_pose[0]
    x1, y1, _ = sim.true_pose[1]
    assert x0 > 0.3 and x1 < -0.3            # they got past each other, each pushed aside to its own side
    assert y0 < 0.0 < 0.05 < y1 and y1 - y0 == pytest.approx(DIAMETER, abs=1e-3)


def test_a_robot_shoves_an_idle_robot_ahead_of_it():
    sim = simulation((-0.3, 0.0, 0.0), (-0.3 + DIAMETER, 0.0, 0.0))   # touching, the front one idle
    sim.command_wheels(0, FULL, FULL)
    run_checked(sim, 100)
    pushed = sim.true_pose[1, 0] - (-0.3 + DIAMETER)
    speed = FULL * MODEL.wheel_radius
    assert pushed == pytest.approx(speed * sim.time, rel=1e-6)
    assert sim.true_twist[:, 0] == pytest.approx([speed, speed])
    assert sim.wheel_speeds[1].tolist() == [0.0, 0.0]
    assert centre_distances(sim)[0] == pytest.approx(DIAMETER, abs=1e-6)


def test_a_row_pushed_into_a_wall_ends_packed_against_it_without_overlap_or_reordering():
    # four robots in a row heading +x towards the wall at x = 0.5, 1 cm apart; only the last one drives
    poses = [(0.1 + i * (DIAMETER + 0.01), 0.0, 0.0) for i in range(4)]
    sim = simulation(*poses, arena=(1.0, 1.0))
    sim.command_wheels(0, FULL, FULL)
    run_checked(sim, 120)   # the pusher needs 43 steps to close the gaps and the 11 cm to the wall
    x = sim.true_pose[:, 0]
    assert np.all(np.diff(x) > 0)                                     # the order along the row is kept
    assert x == pytest.approx([0.5 - RADIUS - DIAMETER * k for k in (3, 2, 1, 0)], abs=1e-5)
    assert sim.true_pose[:, 1] == pytest.approx([0.0] * 4, abs=1e-9)
    assert sim.in_contact.all()
    assert sim.robot_collisions.tolist() == [1, 1, 1, 1]
    assert sim.collisions[3] == 2        # the front robot: one robot contact, then the wall


def test_robots_driving_at_each_other_fast_with_a_long_step_do_not_tunnel():
    sim = simulation((-0.3, 0.0, 0.0), (0.3, 0.0, math.pi), time_step=0.5)   # 6 cm per step each
    for robot in (0, 1):
        sim.command_wheels(robot, FULL, FULL)
    run_checked(sim, 20)
    assert sim.true_pose[0, 0] < sim.true_pose[1, 0]
    assert centre_distances(sim)[0] == pytest.approx(DIAMETER, abs=1e-6)


def test_a_crowd_driving_at_random_never_overlaps():
    world = place_robots(World(arena_size=(0.6, 0.6), boxes=(Box(0.1, 0.1, 0.1, 0.05, 0.3),),
                               cylinders=(Cylinder(-0.15, -0.1, 0.04),)), 20, seed=3)
    sim = Simulation(world, noise=False, cmd_timeout=0.0)
    rng = np.random.default_rng(7)
    for block in range(6):
        for robot, (left, right) in enumerate(rng.uniform(-0.3, 1.0, (20, 2)) * FULL):
            sim.command_wheels(robot, left, right)
        run_checked(sim, 40)
    assert sim.robot_collisions.sum() > 0
    assert np.all(sim.robot_collisions <= sim.collisions)


# --- robots see each other -----------------------------------------------------------------------------------

PS0_YAW = -SENSOR_POSES[0, 2]   # a robot at the origin with this yaw has ps0's ray along +x, from:
PS0_X = math.cos(PS0_YAW) * SENSOR_POSES[0, 0] - math.sin(PS0_YAW) * SENSOR_POSES[0, 1]
PS0_Y = math.sin(PS0_YAW) * SENSOR_POSES[0, 0] + math.cos(PS0_YAW) * SENSOR_POSES[0, 1]


def in_front_of_ps0(gap: float) -> Simulation:
    """Robot 0 at the origin, ps0's ray along +x; robot 1's body `gap` metres ahead of the sensor."""
    return simulation((0.0, 0.0, PS0_YAW), (PS0_X + gap + RADIUS, PS0_Y, 1.0))


@pytest.mark.parametrize('gap', [0.01, 0.02, 0.035, 0.05, 0.0699])   # touching bodies: a 5.4 mm gap
def test_a_sensor_facing_another_robot_reads_the_table(gap):
    sim = in_front_of_ps0(gap)
    assert sim.ir_raw[0, 0] == pytest.approx(raw_from_distance(gap, IR_LOOKUP_TABLE))
    assert sim.ir_range[0, 0] == pytest.approx(gap)
    sim.step()   # and after a step (the pairs found within the step)
    assert sim.ir_range[0, 0] == pytest.approx(gap)


def test_a_robot_beyond_the_ray_is_not_seen_and_a_robot_never_sees_itself():
    sim = in_front_of_ps0(0.0701)
    assert sim.ir_range[0, 0] == math.inf
    alone = simulation((0.0, 0.0, 0.0), (0.8, 0.8, 0.0))
    assert np.isinf(alone.ir_range).all()


def test_robots_side_by_side_see_each_other_on_their_side_sensors():
    sim = simulation((0.0, 0.0, 0.0), (0.0, 0.1, 0.0))   # robot 1 to the left of robot 0
    seen = np.isfinite(sim.ir_range)
    assert seen[0].tolist() == [False, False, False, False, False, True, False, False]   # ps5 looks left
    assert seen[1].tolist() == [False, False, True, False, False, False, False, False]   # ps2 looks right
    assert sim.ir_range[:, [5, 2]].diagonal() == pytest.approx([0.1 - RADIUS - 0.031] * 2)


def test_the_nearest_thing_wins_between_a_robot_and_a_wall():
    wall_ahead = World(arena_size=(2 * (PS0_X + 0.06), 1.0), robots=robots((0.0, 0.0, PS0_YAW)))   # 6 cm
    assert Simulation(wall_ahead, noise=False).ir_range[0, 0] == pytest.approx(0.06)
    between = wall_ahead.with_robots(wall_ahead.robots + (RobotStart('other', PS0_X + 0.03 + RADIUS, PS0_Y),))
    assert Simulation(between, noise=False).ir_range[0, 0] == pytest.approx(0.03)


# --- commands and timeouts are per robot ---------------------------------------------------------------------

def test_each_robot_has_its_own_command_and_timeout():
    sim = simulation((-0.5, 0.0, 0.0), (0.5, 0.0, 0.0), cmd_timeout=0.5)
    sim.command_wheels(0, 2.0, 2.0)
    sim.command_twist(1, 0.05, 0.0)
    timed_out = []
    for step in range(40):
        if step % 5 == 0:
            sim.command_wheels(0, 2.0, 2.0)   # only robot 0 keeps being commanded
        timed_out.append(sim.step().timed_out)
    assert [(i, robots) for i, robots in enumerate(timed_out) if robots] == [(16, [1])]
    assert sim.wheel_speeds[0].tolist() == [2.0, 2.0]
    assert sim.wheel_speeds[1].tolist() == [0.0, 0.0]
    sim.command_twist(1, 0.05, 0.0)   # a new command drives it again
    sim.step()
    assert sim.wheel_speeds[1] == pytest.approx([2.5, 2.5])


def test_commands_name_an_existing_robot():
    sim = simulation((-0.5, 0.0, 0.0), (0.5, 0.0, 0.0))
    for robot in (2, -1, 'r0', 1.0, True):
        with pytest.raises(CommandError, match='no robot'):
            sim.command_wheels(robot, 1.0, 1.0)
    assert not sim.wheel_speeds.any()


def test_names_follow_the_world():
    sim = simulation((-0.5, 0.0, 0.0), (0.5, 0.0, 0.0))
    assert sim.names == ('r0', 'r1')
    assert sim.odom_pose.tolist() == [[0.0, 0.0, 0.0]] * 2   # each robot's odom frame is its start pose


def test_reset_puts_every_robot_back_and_keeps_the_counts():
    sim = simulation((-0.2, 0.0, 0.0), (0.2, 0.0, math.pi))
    for robot in (0, 1):
        sim.command_wheels(robot, FULL, FULL)
    run_checked(sim, 100)
    sim.reset()
    assert sim.true_pose.tolist() == [[-0.2, 0.0, 0.0], [0.2, 0.0, math.pi]]
    assert not sim.in_contact.any() and not sim.wheel_speeds.any()
    assert sim.collisions.tolist() == [1, 1]


# --- determinism and the one-robot path --------------------------------------------------------------------

def crowd_run(seed: int) -> np.ndarray:
    world = place_robots(default_world(), 30, seed=11)
    sim = Simulation(world, seed=seed, noise=True, cmd_timeout=0.0)
    rng = np.random.default_rng(5)
    readings = []
    for block in range(4):
        for robot, (left, right) in enumerate(rng.uniform(-0.3, 1.0, (30, 2)) * FULL):
            sim.command_wheels(robot, left, right)
        for _ in range(30):
            sim.step()
            readings.append(np.concatenate([sim.true_pose.ravel(), sim.ir_raw.ravel(), sim.odom_pose.ravel()]))
    return np.array(readings)


def test_same_seed_same_run_to_the_bit():
    first = crowd_run(seed=4)
    np.testing.assert_array_equal(first, crowd_run(seed=4))
    assert not np.array_equal(first, crowd_run(seed=5))


@pytest.mark.parametrize('count, size', [(30, 0.6), (120, 1.1)])   # all pairs tested, and the cell-list search
def test_searching_the_robot_pairs_only_when_needed_changes_nothing(count, size, monkeypatch):
    """The simulator keeps a wider list of robot pairs for a few steps; a crowd pushing each other runs to the bit as
    with a fresh search every step (the 120 robots differ if close_pairs' order depends on the positions)."""
    def run() -> np.ndarray:
        world = place_robots(World(arena_size=(size, size), boxes=(Box(0.1, 0.1, 0.1, 0.05, 0.3),)), count, seed=2)
        sim = Simulation(world, seed=1, noise=True, cmd_timeout=0.0)
        rng = np.random.default_rng(6)
        states = []
        for block in range(3):
            for robot, (left, right) in enumerate(rng.uniform(-1.0, 1.0, (count, 2)) * FULL):
                sim.command_wheels(robot, left, right)
            for _ in range(25):
                sim.step()
                states.append(np.concatenate([sim.true_pose.ravel(), sim.ir_raw.ravel(), sim.collisions]))
        assert sim.robot_collisions.sum() > 0
        return np.array(states)
    lazy = run()
    cover = SwarmStepper._cover_pairs
    monkeypatch.setattr(SwarmStepper, '_cover_pairs', lambda stepper, xy, refresh=False: cover(stepper, xy, True))
    np.testing.assert_array_equal(lazy, run())


def test_one_robot_moves_the_same_alone_and_among_distant_others():
    """The one-robot float path and the many-robot NumPy path implement the same physics."""
    def drive(world):
        sim = Simulation(world, noise=False, cmd_timeout=0.0)
        rng = np.random.default_rng(2)
        poses = []
        for block in range(8):
            sim.command_wheels(0, *(rng.uniform(-0.3, 1.0, 2) * FULL))
            for _ in range(40):
                sim.step()
                poses.append(np.concatenate([sim.true_pose[0], sim.odom_pose[0], sim.ir_range[0], sim.true_twist[0]]))
        return np.array(poses), sim.collisions[0]
    base = dict(arena_size=(1.0, 2.0), boxes=(Box(0.2, 0.3, 0.1, 0.1, 0.4),), cylinders=(Cylinder(-0.2, -0.2, 0.05),))
    alone, alone_contacts = drive(World(**base))
    # three far robots in the other half of a taller arena: never in reach of robot 0's sensors or body
    walled = World(**base | dict(arena_size=(1.0, 2.0)),
                   robots=robots((0.0, 0.0, 0.0), (0.0, 0.8, 0.0), (0.3, 0.8, 0.0), (-0.3, 0.8, 1.0)))
    among, among_contacts = drive(walled)
    assert alone_contacts > 0 and alone_contacts == among_contacts
    np.testing.assert_allclose(among, alone, atol=1e-9)


@pytest.mark.parametrize('count, spread', [(2, 0.1), (40, 0.5), (300, 2.0), (1500, 5.0), (500, 100.0)])
def test_close_pairs_finds_exactly_the_pairs_within_reach(count, spread):
    xy = np.random.default_rng(count).uniform(-spread, spread, (count, 2))
    first, second = close_pairs(xy, 0.15)
    found = set(zip(first.tolist(), second.tolist()))
    assert len(found) == len(first)   # each pair once
    assert np.all(first < second) and np.all(np.diff(first * count + second) > 0)   # in the one canonical order
    everyone = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    expected = {(i, j) for i, j in zip(*np.nonzero(np.triu(everyone < 0.15, 1)))}
    assert found == expected


# --- placement -------------------------------------------------------------------------------------------------

def test_place_robots_is_seeded_clear_and_named():
    world = place_robots(default_world(), 40, seed=1)
    assert world.names == tuple(f'epuck{i}' for i in range(40))
    assert world == place_robots(default_world(), 40, seed=1)
    assert world != place_robots(default_world(), 40, seed=2)
    xy = np.array([r.pose[:2] for r in world.robots])
    assert world.clearance(xy).min() > RADIUS
    first, second = np.triu_indices(40, 1)
    assert np.hypot(*(xy[first] - xy[second]).T).min() > DIAMETER
    assert world.boxes == default_world().boxes
    assert world_from_dict(world.to_dict()) == world   # checked like a world file


def test_a_huge_arena_costs_seconds_and_megabytes_not_hours_and_gigabytes():
    world = world_from_dict({'arena': {'size': [10000.0, 10000.0]}, 'cylinders': [{'position': [3, 3], 'radius': 0.1}],
                             'boxes': [{'position': [1, 1], 'size': [0.1, 0.1]}]})
    sim = Simulation(place_robots(world, 300, seed=0), noise=False)   # grids and maps are bounded in size
    sim.step()
    assert np.isfinite(sim.true_pose).all()


def test_place_robots_refuses_more_than_fit_naming_the_field():
    with pytest.raises(WorldError, match=r'^robots: 500 robots do not fit'):
        place_robots(default_world(), 500, seed=0)
    with pytest.raises(WorldError, match=r'^robots: '):
        place_robots(default_world(), 0, seed=0)
