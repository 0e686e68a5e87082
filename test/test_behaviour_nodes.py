"""The behaviour executables over DDS: the real `sim` process (lockstep, as fast as the behaviour answers) and a
real behaviour process (use_sim_time), judged on the `ground_truth` and `odom` topics a test node reads. Figures
and tolerances are those of the pure closed-loop tests in test_behaviours.py."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import Float64MultiArray, UInt32

from conftest import ALONE_ON_THE_DOMAIN, EVERY_MESSAGE, ros_args, set_sim_parameter
from epuck_ros.nodes.behaviour_nodes import RangeAssembler
from test_behaviours import fitted_circle

SIM_PARAMS = {**ALONE_ON_THE_DOMAIN, 'real_time_factor': 0.0, 'lockstep': True}
"""The sim waits for the behaviour's command after each step: the run is the same however busy the machine is."""
REAL_TIME_FACTOR = 5.0
"""What lockstep runs reach here (3.5x to 10x real time); the waits below allow a third of it."""


# --- message conversion, no DDS ---------------------------------------------------------------------------------

def test_range_assembler_hands_over_only_complete_cycles_in_sensor_order() -> None:
    assembler = RangeAssembler()
    for i in (7, 0, 1, 2, 3, 4, 5):
        assert assembler.add(f'ps{i}', (1, 0), 0.01 * i) is None
    assert assembler.add('ps6', (1, 0), math.inf) == (0.0, 0.01, 0.02, 0.03, 0.04, 0.05, math.inf, 0.07)
    assert assembler.add('ps6', (1, 0), 0.5) is None  # a duplicate does not hand the cycle over again


def test_range_assembler_drops_an_interrupted_cycle_and_ignores_frame_prefixes() -> None:
    assembler = RangeAssembler()
    for i in range(4):
        assembler.add(f'ps{i}', (1, 0), 0.03)
    results = [assembler.add(f'robot1/ps{i}', (1, 32_000_000), 0.05) for i in range(8)]
    assert results[:7] == [None] * 7 and results[7] == (0.05,) * 8
    with pytest.raises(KeyError):
        assembler.add('ps8', (2, 0), 0.05)


# --- processes ----------------------------------------------------------------------------------------------------

def trajectory(messages: list[Odometry]) -> np.ndarray:
    """Rows of (t, x, y, yaw) with the yaw unwrapped, one per step: a step sent again (lockstep sends a first step
    again to a controller that has not answered it within a second: on a loaded machine) is kept once."""
    rows = np.array([(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, m.pose.pose.position.x,
                      m.pose.pose.position.y, 2.0 * math.atan2(m.pose.pose.orientation.z, m.pose.pose.orientation.w))
                     for m in messages])
    rows = rows[np.concatenate(([True], np.diff(rows[:, 0]) != 0.0))]
    rows[:, 3] = np.unwrap(rows[:, 3])
    return rows


def moving(rows: np.ndarray) -> np.ndarray:
    """The rows from the first pose change to the last one."""
    changed = np.flatnonzero(np.any(np.diff(rows[:, 1:], axis=0) != 0.0, axis=1))
    return rows[changed[0]:changed[-1] + 2]


class Run:
    """`sim` and one behaviour, started in this order, with the test node reading ground_truth and odom."""

    def __init__(self, launch: object, test_node: object, behaviour: str, params: dict, noise: bool = False) -> None:
        self.test_node = test_node
        self.truth: list[Odometry] = test_node.collect(Odometry, 'ground_truth', EVERY_MESSAGE)
        self.odom: list[Odometry] = test_node.collect(Odometry, 'odom', EVERY_MESSAGE)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.collisions: list[UInt32] = test_node.collect(UInt32, 'collisions', latched)
        self.sim = launch('sim', *ros_args({**SIM_PARAMS, 'noise': noise, 'paused': True}))
        test_node.wait_for_simulator()
        # Resumed once the test node's readers are matched (from the graph): every step's ground truth is read,
        # however long discovery takes on a busy machine.
        readers = [sub for sub in test_node.node.subscriptions if sub.topic_name in ('/ground_truth', '/odom')]
        test_node.spin_until(lambda: all(sub.get_publisher_count() for sub in readers), timeout=30.0,
                             what='the sim matched with the test node')
        # its state changes ('driving', 'cruising'), which the tests wait for, are DEBUG lines
        self.behaviour = launch(behaviour, *ros_args({'use_sim_time': True, **params}), '--log-level',
                                f'{behaviour}:=debug')
        set_sim_parameter(test_node, self.sim, 'paused', False)

    def wait_for(self, process: object, text: str, timeout: float = 20.0) -> None:
        """Like `wait_for_output`, but spinning: the test node must keep up with ground_truth meanwhile."""
        self.test_node.spin_until(lambda: text in process.output() or process.proc.poll() is not None,
                                  timeout=timeout, what=f'{process.name} to print {text!r}')
        assert text in process.output(), process.output()

    def logged_time(self, process: object, text: str) -> float:
        """The simulated time of the behaviour's log line containing `text` ("... (t=12.345 s)"): the test node's
        view of ground_truth may lag the simulator, so waits for what followed start from this time."""
        line = next(line for line in process.output().splitlines() if text in line)
        return float(re.search(r'\(t=([0-9.]+) s\)', line).group(1))

    def sim_time(self) -> float:
        stamp = self.truth[-1].header.stamp if self.truth else None
        return stamp.sec + 1e-9 * stamp.nanosec if stamp else 0.0

    def until(self, seconds: float) -> None:
        """Spin the test node until the simulation has run `seconds` of simulated time."""
        self.test_node.spin_until(lambda: self.sim_time() >= seconds, timeout=5.0 + 3.0 * seconds / REAL_TIME_FACTOR,
                                  what=f'{seconds} s of simulated time')


def test_forward_stops_at_its_goal_over_dds(launch: object, test_node: object) -> None:
    run = Run(launch, test_node, 'forward', {'goal_distance': 0.2})
    run.wait_for(run.behaviour, 'goal reached', timeout=20.0)
    run.until(run.logged_time(run.behaviour, 'goal reached') + 1.0)
    truth, odom = trajectory(run.truth), trajectory(run.odom)
    travelled = float(np.hypot(*(truth[-1, 1:3] - truth[0, 1:3])))
    on_odom = float(np.hypot(*(odom[-1, 1:3] - odom[0, 1:3])))
    cruise = moving(truth)
    cruise = cruise[(cruise[:, 1] - truth[0, 1] > 0.02) & (cruise[:, 1] - truth[0, 1] < 0.15)]
    speed = np.polyfit(cruise[:, 0], cruise[:, 1], 1)[0]
    heading_change = math.degrees(abs(truth[-1, 3] - truth[0, 3]))
    print(f'forward over DDS: {speed:.5f} m/s, stopped at {travelled:.5f} m (odom {on_odom:.5f}) of 0.2, '
          f'heading change {heading_change:.4f} deg')
    assert speed == pytest.approx(0.0628, rel=0.02)
    assert travelled == pytest.approx(0.2, abs=0.005)
    assert on_odom == pytest.approx(0.2, abs=0.005)
    assert heading_change < 1.0


def test_spin_turns_in_place_over_dds(launch: object, test_node: object) -> None:
    run = Run(launch, test_node, 'spin', {})
    run.wait_for(run.behaviour, 'driving')
    run.until(run.sim_time() + 6.0)
    rows = moving(trajectory(run.truth))[5:-5]
    rate = np.polyfit(rows[:, 0], rows[:, 3], 1)[0]
    drift = float(np.hypot(*(rows[:, 1:3] - rows[0, 1:3]).T).max())
    print(f'spin over DDS: {rate:.4f} rad/s, largest drift {drift * 1000:.4f} mm')
    assert rate == pytest.approx(-2.415, rel=0.02)
    assert drift < 0.002


def test_circle_has_the_course_radius_over_dds(launch: object, test_node: object) -> None:
    run = Run(launch, test_node, 'circle', {})
    run.wait_for(run.behaviour, 'driving')
    run.until(run.sim_time() + 10.0)
    _, _, radius = fitted_circle(moving(trajectory(run.truth))[:, 1:3])
    print(f'circle over DDS: fitted radius {radius:.5f} m')
    assert radius == pytest.approx(0.078, rel=0.03)


def test_rectangle_closes_with_true_right_angles_over_dds(launch: object, test_node: object) -> None:
    run = Run(launch, test_node, 'rectangle', {'laps': 1})
    run.wait_for(run.behaviour, 'finished 1 lap', timeout=30.0)
    run.until(run.logged_time(run.behaviour, 'finished 1 lap') + 0.5)
    rows = trajectory(run.truth)
    turning = np.abs(np.diff(rows[:, 3])) > 0.0
    starts = np.flatnonzero(np.diff(turning.astype(int)) == 1) + 1
    ends = np.flatnonzero(np.diff(turning.astype(int)) == -1) + 1
    angles = np.degrees(rows[ends, 3] - rows[starts, 3])
    closure = float(np.hypot(*(rows[-1, 1:3] - rows[0, 1:3])))
    print(f'rectangle over DDS: corners {np.round(angles, 3)} deg, back within {closure * 1000:.2f} mm')
    assert len(angles) == 4
    assert np.allclose(angles, 90.0, atol=2.0)
    assert closure < 0.01


@pytest.mark.parametrize('mode', ['rules', 'braitenberg'])
def test_avoid_drives_without_a_collision_over_dds(launch: object, test_node: object, mode: str) -> None:
    """30 simulated seconds, noise on: no contact, and cruising at least half of the time (see the pure test)."""
    run = Run(launch, test_node, 'avoid', {'mode': mode}, noise=True)
    run.wait_for(run.behaviour, 'cruising')
    start = run.sim_time()
    run.until(start + 30.0)
    rows = trajectory(run.truth)
    rows = rows[rows[:, 0] >= start]
    distance = float(np.hypot(*np.diff(rows[:, 1:3], axis=0).T).sum())
    collisions = max(m.data for m in run.collisions)
    print(f'avoid {mode} over DDS: {collisions} collisions, {distance:.3f} m in 30 s')
    assert collisions == 0
    assert distance > 0.5 * 0.0628 * 30.0


def test_a_behaviour_without_its_inputs_commands_stop_and_says_so_once(launch: object, test_node: object) -> None:
    commands: list[Float64MultiArray] = test_node.collect(Float64MultiArray, 'wheel_cmd')
    avoid = launch('avoid')  # wall clock, no sim: no proximity ever arrives
    test_node.spin_until(lambda: len(commands) >= 5, what='5 wheel commands')
    assert all(list(c.data) == [0.0, 0.0] for c in commands)
    assert avoid.output().count('waiting for proximity: wheels stopped') == 1


@pytest.mark.parametrize('param, named', [('turn_mode:=square', 'turn_mode'), ('laps:=-1', 'laps'),
                                          ('side_a:=abc', 'side_a'), ('side_a:=0', 'side_a')])
def test_a_bad_parameter_stops_the_node_with_a_message_naming_it(launch: object, param: str, named: str) -> None:
    rectangle = launch('rectangle', '--ros-args', '-p', param)
    assert rectangle.proc.wait(timeout=15.0) == 2
    output = rectangle.output()
    assert named in output and 'Traceback' not in output


def test_a_step_sent_again_is_answered_again_with_the_same_answer(launch: object, test_node: object) -> None:
    """The simulator sends a step again while it has no answer to it; the answer may never have reached it (a writer
    that matched the simulator's reader only after publishing sends it nothing it had published: a fixture run
    stood still for 120 s under load, the behaviour having answered the step once). Each copy of the step's
    `ir_raw` gets the same answer, naming that step; the simulator drops the second as a repeat."""
    from rosgraph_msgs.msg import Clock
    from epuck_ros.conversions import stamp_from_label
    from epuck_ros.ros.serialized import array_bytes
    answers: list[Float64MultiArray] = test_node.collect(Float64MultiArray, 'wheel_cmd', EVERY_MESSAGE)
    clock = test_node.node.create_publisher(Clock, '/clock', 10)
    ir_raw = test_node.node.create_publisher(Float64MultiArray, 'ir_raw', 10)
    launch('avoid', *ros_args({'use_sim_time': True}))
    test_node.spin_until(lambda: ir_raw.get_subscription_count() and clock.get_subscription_count(),
                         what='avoid to read ir_raw and /clock')
    step = Clock()
    step.clock.nanosec = 32_000_000
    for copy in range(2):
        clock.publish(step)
        ir_raw.publish(array_bytes([100.0] * 8, (0, 32_000_000)))
        test_node.spin_until(lambda: len(answers) > copy, what=f'the answer to copy {copy + 1} of the step')
    assert [stamp_from_label(answer.layout.dim[0].label) for answer in answers] == [(0, 32_000_000)] * 2
    assert answers[0].data.tolist() == answers[1].data.tolist()
