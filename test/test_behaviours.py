"""The course behaviours without ROS: each state machine on made-up observations, then in closed loop with the
pure simulator (`Simulation`), judged on the robot's true pose."""
from __future__ import annotations

import math

import numpy as np
import pytest

from epuck_ros.bag.shapes import fit_circle
from epuck_ros.behaviours import BEHAVIOURS, STOP, Avoid, AvoidConfig, Behaviour, ConfigError, Forward, \
    ForwardConfig, Observation, Rectangle, RectangleConfig, WheelCommand
from epuck_ros.behaviours.avoid import COURSE_THRESHOLD, braitenberg
from epuck_ros.behaviours.base import FREE_READING_SIGMAS, describe, ranges_from_raw
from epuck_ros.ir_sensor import raw_from_distance
from epuck_ros.model import IR_LOOKUP_TABLE, MAX_WHEEL_SPEED
from epuck_ros.simulation import Simulation
from epuck_ros.world import World, default_world

DT = 0.032
FREE = (math.inf,) * 8


def fractions(command: WheelCommand) -> tuple[float, float]:
    return round(command.left / MAX_WHEEL_SPEED, 6), round(command.right / MAX_WHEEL_SPEED, 6)


def ranges(**close: float) -> tuple[float, ...]:
    """Eight ranges, inf except the named sensors (ps0=0.03 and so on)."""
    return tuple(close.get(f'ps{i}', math.inf) for i in range(8))


# --- the state machines on made-up observations -------------------------------------------------------------

@pytest.mark.parametrize('name, expected', [('forward', (0.5, 0.5)), ('spin', (0.5, -0.5)), ('circle', (0.3, 0.6))])
def test_open_loop_behaviours_drive_the_course_speeds_without_any_input(name: str, expected: tuple) -> None:
    spec = BEHAVIOURS[name]
    behaviour = spec.make(spec.defaults)
    assert fractions(behaviour.update(Observation(0.0))) == expected
    assert not behaviour.done


@pytest.mark.parametrize('behaviour, missing', [
    (Forward(ForwardConfig(goal_distance=0.5)), 'odom'),
    (Rectangle(RectangleConfig()), 'odom'),
    (Avoid(AvoidConfig()), 'proximity'),
])
def test_a_behaviour_stops_until_it_has_heard_what_it_needs(behaviour: object, missing: str) -> None:
    assert behaviour.update(Observation(0.0)) == STOP
    assert behaviour.status == f'waiting for {missing}: wheels stopped'
    moving = behaviour.update(Observation(DT, odom=(0.0, 0.0, 0.0), ranges=FREE))
    assert moving != STOP
    assert behaviour.status == behaviour.state and 'waiting' not in behaviour.status


def test_timed_rectangle_needs_nothing_and_avoid_needs_no_odometry() -> None:
    assert Rectangle(RectangleConfig(turn_mode='timed')).update(Observation(0.0)) != STOP
    assert Avoid(AvoidConfig()).update(Observation(0.0, ranges=FREE)) != STOP


def test_forward_slows_down_near_the_goal_then_stops_for_good() -> None:
    heading = math.radians(30.0)
    forward = Forward(ForwardConfig(goal_distance=0.2))

    def at(distance: float) -> tuple[float, float]:
        odom = (1.0 + distance * math.cos(heading), 2.0 + distance * math.sin(heading), heading)
        return fractions(forward.update(Observation(0.0, odom=odom)))

    assert at(0.0) == (0.5, 0.5)
    assert at(0.15) == (0.5, 0.5)
    left, right = at(0.195)
    assert left == right and 0.02 < left < 0.5
    assert at(0.1993) == (0.02, 0.02)  # the minimum speed, 0.08 mm per step
    assert not forward.done
    assert at(0.1996) == (0.0, 0.0)  # within 0.5 mm
    assert forward.done and 'goal reached: 0.1996 m' in forward.state
    assert at(0.1) == (0.0, 0.0)  # done means done, wherever odometry says it is


def test_forward_goal_backwards_measures_progress_behind_the_start() -> None:
    forward = Forward(ForwardConfig(speed=-0.5, goal_distance=0.1))
    assert fractions(forward.update(Observation(0.0, odom=(0.0, 0.0, 0.0)))) == (-0.5, -0.5)
    assert fractions(forward.update(Observation(0.0, odom=(-0.1, 0.0, 0.0)))) == (0.0, 0.0)
    assert forward.done


def timed_commands(config: RectangleConfig, seconds: float) -> list[tuple[float, float]]:
    rectangle = Rectangle(config)
    return [fractions(rectangle.update(Observation(k * DT))) for k in range(round(seconds / DT))]


def runs(commands: list[tuple[float, float]]) -> list[tuple[tuple[float, float], int]]:
    """Run-length encoding: [(command, ticks), ...]."""
    out: list[tuple[tuple[float, float], int]] = []
    for command in commands:
        if out and out[-1][0] == command:
            out[-1] = (command, out[-1][1] + 1)
        else:
            out.append((command, 1))
    return out


def test_timed_rectangle_is_the_course_state_machine_to_the_nearest_tick() -> None:
    # 5 s = 156.25 ticks -> 156; 1 s = 31.25 ticks -> 31.
    assert runs(timed_commands(RectangleConfig(turn_mode='timed'), 13.0))[:4] == [
        ((0.5, 0.5), 156), ((-0.3, 0.3), 31), ((0.5, 0.5), 156), ((-0.3, 0.3), 31)]


def test_timed_rectangle_sides_become_times_and_negative_turn_speed_turns_right() -> None:
    config = RectangleConfig(turn_mode='timed', side_a=0.0628, side_b=0.1256, turn_speed=-0.4, turn_time=0.5)
    assert runs(timed_commands(config, 6.0))[:5] == [
        ((0.5, 0.5), 31), ((0.4, -0.4), 16), ((0.5, 0.5), 62), ((0.4, -0.4), 16), ((0.5, 0.5), 31)]


def test_odometry_rectangle_aims_at_ideal_corners_and_headings() -> None:
    rectangle = Rectangle(RectangleConfig(side_a=0.3, side_b=0.2, laps=1))

    def at(x: float, y: float, yaw_deg: float) -> tuple[float, float]:
        return fractions(rectangle.update(Observation(0.0, odom=(x, y, math.radians(yaw_deg)))))

    assert at(0.0, 0.0, 0.0) == (0.5, 0.5)
    assert at(0.2993, 0.001, 0.0) == (0.02, 0.02)
    assert at(0.2996, 0.001, 0.0) == (-0.3, 0.3)  # side 1 done: turn left at full turn speed
    assert 'corner 1/4' in rectangle.state
    left, right = at(0.3, 0.0, 85.0)
    assert left == -right and 0.01 < right < 0.3  # slowing down near 90 degrees
    assert at(0.3, 0.0, 90.3) == (0.01, -0.01)  # overshot: come back, slowly
    assert at(0.3, 0.0, 89.9) == (0.5, 0.5)  # within 0.15 degree: side 2 (side_b) starts
    assert 'side 2/4: forward 0.200 m' in rectangle.state
    assert at(0.31, 0.15, 90.0) == (0.5, 0.5)
    assert at(0.31, 0.1996, 90.0)[0] == -0.3  # side 2 ends at the ideal corner (0.3, 0.2), not 0.2 from here
    for x, y, yaw in ((0.3, 0.2, 180.0), (0.0, 0.2, 180.0), (0.0, 0.2, -90.0), (0.0, 0.0, -90.0)):
        at(x, y, yaw)  # finishes corner 2, side 3, corner 3, side 4
    assert not rectangle.done
    assert at(0.0, 0.0, 0.0) == (0.0, 0.0)
    assert rectangle.done and 'finished 1 lap' in rectangle.state


def test_avoid_rules_turn_away_from_the_front_until_clear_with_hysteresis() -> None:
    avoid = Avoid(AvoidConfig())

    def sees(**close: float) -> tuple[float, float]:
        return fractions(avoid.update(Observation(0.0, ranges=ranges(**close))))

    assert sees() == (0.5, 0.5)
    assert sees(ps1=0.06) == (-0.4, 0.4)  # front right: turn left, as the course does
    assert sees(ps6=0.03) == (-0.4, 0.4)  # a corner: keeps its direction instead of rocking
    assert sees(ps7=0.068) == (-0.4, 0.4)  # beyond the threshold but not clear yet
    assert sees() == (0.5, 0.5)
    assert sees(ps7=0.06) == (0.4, -0.4)  # front left: turn right
    assert sees(ps0=0.069, ps2=0.01) == (0.4, -0.4)


@pytest.mark.parametrize('close, expected', [
    ({'ps2': 0.05}, (0.2, 0.5)),  # obstacle on the right: veer left, away from it (the course veers right)
    ({'ps5': 0.05}, (0.5, 0.2)),  # on the left: veer right
    ({'ps2': 0.05, 'ps5': 0.05}, (0.5, 0.5)),  # a corridor: straight on
    ({'ps2': 0.068, 'ps3': 0.01, 'ps4': 0.01}, (0.5, 0.5)),  # beyond the threshold, and the back sensors are ignored
])
def test_avoid_rules_veer_away_from_a_side_obstacle(close: dict, expected: tuple) -> None:
    assert fractions(Avoid(AvoidConfig()).update(Observation(0.0, ranges=ranges(**close)))) == expected


def test_avoid_threshold_is_the_course_raw_value_80() -> None:
    assert COURSE_THRESHOLD == pytest.approx(0.06653, abs=1e-5)


def test_ranges_from_raw_readings_are_the_simulators_ranges_and_a_free_sensor_reads_inf() -> None:
    """What a node reading `ir_raw` sees: the inverse table where something is seen, inf for a free sensor even
    with its noise (the table's last row: raw 67.19, 4.897 % standard deviation), the course's raw 80 threshold."""
    far_raw, far_noise = IR_LOOKUP_TABLE[-1, 1:]
    free = far_raw * (1.0 + np.array([-3.0, -1.0, 0.0, 1.0, 2.0, 2.9, FREE_READING_SIGMAS - 1e-9, 0.0]) * far_noise)
    assert ranges_from_raw(free) == (math.inf,) * 8
    assert ranges_from_raw([80.0] * 8)[0] == pytest.approx(COURSE_THRESHOLD, abs=1e-12)
    distances = np.array([0.0, 0.005, 0.012, 0.02, 0.033, 0.05, 0.06, 0.065])
    assert ranges_from_raw(raw_from_distance(distances, IR_LOOKUP_TABLE)) == pytest.approx(distances, abs=1e-12)
    sim = Simulation(default_world(), seed=3, noise=True)  # straight into the wall ahead, 0.46 m away
    seen_count = 0
    while not sim.in_contact[0]:
        sim.command_wheels(0, 1.0, 1.0)
        sim.step()
        seen = sim.ir_range[0] < 0.0673  # closer than the free sensor's noise band: both must agree
        seen_count += int(seen.sum())
        assert np.array(ranges_from_raw(sim.ir_raw[0]))[seen] == pytest.approx(sim.ir_range[0][seen], abs=1e-12)
    assert seen_count > 20


def test_braitenberg_is_webots_e_puck_avoid_obstacles() -> None:
    # nothing in range: every sensor reads raw 67.19, the weights bend the path slightly left (Webots does too)
    free = braitenberg(np.array(FREE), 0.5)
    assert free.left == pytest.approx(3.14 - 4.55 * 67.19 / 4096 * 6.28)
    assert free.right == pytest.approx(3.14 - 2.0 * 67.19 / 4096 * 6.28)
    touching = braitenberg(np.array(ranges(ps0=0.0)), 0.5)  # raw 4095 front right: back off turning left
    assert -MAX_WHEEL_SPEED < touching.left < touching.right < 0.0
    assert fractions(braitenberg(np.array(ranges(ps0=0.0, ps1=0.0)), 0.5)) == (-1.0, -1.0)  # clipped
    right = braitenberg(np.array(ranges(ps2=0.005)), 0.5)
    assert right.left < right.right  # obstacle on the right: turn left


def test_braitenberg_mode_steers_on_the_weights_until_the_front_escape_takes_over() -> None:
    avoid = Avoid(AvoidConfig(mode='braitenberg'))
    side = ranges(ps2=0.02)
    assert avoid.update(Observation(0.0, ranges=side)) == braitenberg(np.array(side), 0.5)
    assert fractions(avoid.update(Observation(0.0, ranges=ranges(ps7=0.06)))) == (0.4, -0.4)
    assert fractions(avoid.update(Observation(0.0, ranges=ranges(ps7=0.069)))) == (0.4, -0.4)
    assert avoid.update(Observation(0.0, ranges=FREE)) == braitenberg(np.array(FREE), 0.5)


@pytest.mark.parametrize('make, field', [
    (lambda: RectangleConfig(turn_mode='square'), 'turn_mode'),
    (lambda: RectangleConfig(side_a=-1.0), 'side_a'),
    (lambda: RectangleConfig(turn_speed=0.0), 'turn_speed'),
    (lambda: AvoidConfig(threshold=0.1), 'threshold'),
    (lambda: AvoidConfig(threshold=0.05, release_distance=0.04), 'release_distance'),
    (lambda: AvoidConfig(mode='wall-follow'), 'mode'),
    (lambda: ForwardConfig(speed=0.0, goal_distance=1.0), 'speed'),
])
def test_bad_settings_name_what_is_wrong(make: object, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        make()


@pytest.mark.parametrize('name', sorted(BEHAVIOURS))
def test_every_setting_has_a_description_and_a_default_inside_its_range(name: str) -> None:
    for setting, value, description, (low, high) in describe(BEHAVIOURS[name].defaults):
        assert len(description) > 20, setting
        assert low is None or low <= value <= high, setting


# --- closed loop with the pure simulator, judged on the true pose ---------------------------------------------

OPEN_FLOOR = World(arena_size=(4.0, 4.0))
"""Nothing to bump into: the kinematic behaviours are judged on kinematics alone."""


def drive(behaviour: Behaviour, sim: Simulation, seconds: float,
          from_raw: bool = False) -> tuple[np.ndarray, list[str]]:
    """Run the behaviour on the simulator as a node would; the true pose before and after every step (unwrapped
    yaw), and the behaviour's state during each step. `from_raw`: ranges from the raw readings, as a node reading
    `ir_raw` gets them, instead of the simulator's ranges (its `proximity` topic)."""
    poses, states = [sim.true_pose[0].copy()], []
    for _ in range(round(seconds / sim.time_step)):
        ranges = ranges_from_raw(sim.ir_raw[0]) if from_raw else tuple(sim.ir_range[0])
        command = behaviour.update(Observation(sim.time, tuple(sim.odom_pose[0]), ranges))
        states.append(behaviour.state)
        sim.command_wheels(0, command.left, command.right)
        sim.step()
        poses.append(sim.true_pose[0].copy())
    poses = np.array(poses)
    poses[:, 2] = np.unwrap(poses[:, 2])
    return poses, states


def segments(states: list[str], word: str) -> list[tuple[int, int]]:
    """(first, last + 1) step indices of each run of states containing `word`."""
    runs, start = [], None
    for index, state in enumerate([*states, '']):
        if start is not None and (state != states[start]):
            runs.append((start, index))
            start = None
        if start is None and word in state:
            start = index
    return runs


def noiseless(world: World = OPEN_FLOOR) -> Simulation:
    return Simulation(world, noise=False)


def path_length(poses: np.ndarray) -> float:
    return float(np.hypot(*np.diff(poses[:, :2], axis=0).T).sum())


def test_closed_loop_forward_drives_straight_at_the_course_speed() -> None:
    sim = noiseless()
    poses, _ = drive(Forward(ForwardConfig()), sim, 10.0)
    speed = path_length(poses) / sim.time
    heading_change = math.degrees(abs(poses[-1, 2] - poses[0, 2]))
    print(f'forward: {speed:.5f} m/s (course 0.0628), heading change {heading_change:.4f} deg')
    assert speed == pytest.approx(0.5 * MAX_WHEEL_SPEED * 0.02, rel=0.02)
    assert heading_change < 1.0


@pytest.mark.parametrize('goal', [0.05, 0.314, 1.0])
def test_closed_loop_forward_stops_within_5_mm_of_its_goal(goal: float) -> None:
    forward = Forward(ForwardConfig(goal_distance=goal))
    poses, states = drive(forward, noiseless(), goal / 0.0628 + 5.0)
    assert forward.done
    reached = states.index(forward.state)
    travelled = float(np.hypot(*(poses[-1, :2] - poses[0, :2])))
    print(f'forward goal {goal} m: stopped at {travelled:.5f} m (true) after {reached * DT:.2f} s')
    assert travelled == pytest.approx(goal, abs=0.005)
    assert np.allclose(poses[reached + 1:], poses[-1])  # and stays there


def test_closed_loop_spin_turns_in_place_at_2_415_rad_s() -> None:
    sim = noiseless()
    poses, _ = drive(BEHAVIOURS['spin'].make(BEHAVIOURS['spin'].defaults), sim, 10.0)
    rate = (poses[-1, 2] - poses[0, 2]) / sim.time
    drift = float(np.hypot(*(poses[:, :2] - poses[0, :2]).T).max())
    print(f'spin: {rate:.4f} rad/s (course -2.415), largest drift {drift * 1000:.4f} mm')
    assert rate == pytest.approx(-0.02 / 0.052 * MAX_WHEEL_SPEED, rel=0.02)
    assert drift < 0.002


def fitted_circle(xy: np.ndarray) -> tuple[float, float, float]:
    """Centre x, y and radius of the least-squares circle through the points (N, 2): `bag summary`'s fit."""
    radius, (x, y), _ = fit_circle(xy[:, 0], xy[:, 1])
    return x, y, radius


def test_closed_loop_circle_has_the_course_radius() -> None:
    poses, _ = drive(BEHAVIOURS['circle'].make(BEHAVIOURS['circle'].defaults), noiseless(), 20.0)
    x, y, radius = fitted_circle(poses[:, :2])
    print(f'circle: fitted radius {radius:.5f} m (course 0.078), centre ({x:.4f}, {y:.4f})')
    assert radius == pytest.approx(0.026 * 0.9 / 0.3, rel=0.03)
    assert (x, y) == pytest.approx((0.0, radius), abs=0.002)  # counter-clockwise: the centre is on the left


def corner_angles(poses: np.ndarray, states: list[str]) -> list[float]:
    return [math.degrees(poses[end, 2] - poses[start, 2]) for start, end in segments(states, 'corner')]


@pytest.mark.parametrize('config', [
    RectangleConfig(laps=1),
    RectangleConfig(laps=1, side_a=0.3, side_b=0.15, turn_speed=-0.3),
], ids=['course-square-left', 'rectangle-right'])
def test_closed_loop_odometry_rectangle_closes_with_true_right_angles(config: RectangleConfig) -> None:
    rectangle = Rectangle(config)
    poses, states = drive(rectangle, noiseless(default_world()), 40.0)
    assert rectangle.done
    angles = corner_angles(poses, states)
    corners = [poses[start, :2] for start, _ in segments(states, 'corner')]
    sides = np.hypot(*np.diff([poses[0, :2], *corners], axis=0).T)
    closure = float(np.hypot(*(poses[-1, :2] - poses[0, :2])))
    print(f'rectangle {config.side_a}x{config.side_b}: corners {np.round(angles, 3)} deg, '
          f'sides {np.round(sides, 4)} m, back within {closure * 1000:.2f} mm of the start')
    assert len(angles) == 4
    assert np.allclose(angles, math.copysign(90.0, config.turn_speed), atol=2.0)
    assert np.allclose(sides, [config.side_a, config.side_b, config.side_a, config.side_b], atol=0.005)
    assert closure < 0.01


def test_closed_loop_timed_rectangle_turns_the_courses_83_degrees() -> None:
    poses, states = drive(Rectangle(RectangleConfig(turn_mode='timed', laps=1)), noiseless(default_world()), 30.0)
    angles = corner_angles(poses, states)
    print(f'timed rectangle: corners {np.round(angles, 3)} deg (1 s at 1.449 rad/s = 83.0)')
    assert len(angles) == 4
    assert np.allclose(angles, 83.0, atol=1.5)


@pytest.mark.parametrize('from_raw', [False, True], ids=['ranges', 'raw'])
@pytest.mark.parametrize('mode', ['rules', 'braitenberg'])
def test_closed_loop_avoid_explores_the_default_world_for_5_minutes_without_a_collision(
        mode: str, from_raw: bool) -> None:
    """Bounds: cruising the whole time would drive 0.0628 m/s * 300 s = 18.8 m; at least half of that says the
    robot is not stuck turning. The 1 m arena has 100 cells of 10 cm and a wall-follower would visit only the
    36 along the walls; 40 says it crosses the room. Seeds 0 to 19 drove 12.0 to 17.1 m over 45 to 84 cells."""
    sim = Simulation(default_world(), seed=0, noise=True)
    poses, _ = drive(Avoid(AvoidConfig(mode=mode)), sim, 300.0, from_raw)
    distance = path_length(poses)
    cells = len(set(map(tuple, np.floor((poses[:, :2] + 0.5) / 0.1).astype(int))))
    print(f'avoid {mode} on {"raw readings" if from_raw else "ranges"}: {sim.collisions[0]} collisions, '
          f'{distance:.2f} m driven, {cells} of 100 cells visited')
    assert sim.collisions[0] == 0
    assert distance > 0.5 * 0.0628 * 300.0
    assert cells >= 40
