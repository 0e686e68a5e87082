"""The `sim` executable in its own process, checked over DDS by a node in the test process."""
from __future__ import annotations

import math
import signal
import time
from pathlib import Path

import pytest
from conftest import EVERY_MESSAGE, ros_args
from geometry_msgs.msg import Twist, Vector3
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, Range
from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String, UInt32
from std_srvs.srv import Empty
from visualization_msgs.msg import MarkerArray

from epuck_ros.conversions import stamp_label
from epuck_ros.lockstep import DECLARATION_TOPIC, Controller, declaration
from epuck_ros.model import MAX_WHEEL_SPEED, SENSOR_NAMES
from epuck_ros.ros.qos import DECLARATIONS_READ, LATCHED
from epuck_ros.ros.robot_ports import WARN_PERIOD
from epuck_ros.nodes.sim_node import publication_mode
from epuck_ros.webots.link import SimLink

HALF_SPEED = 0.5 * MAX_WHEEL_SPEED
LINEAR_SPEED = HALF_SPEED * 0.02  # 0.0628 m/s
STEP = 0.032
"""A reader that loses nothing it has not taken yet."""


def stamp_seconds(msg: object) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def stamp_seconds_of(clock: Clock) -> float:
    return clock.clock.sec + clock.clock.nanosec * 1e-9


def start_sim(launch, test_node, **params):
    sim = launch('sim', *ros_args({'noise': False, 'real_time_factor': 5.0, **params}))
    test_node.wait_for_simulator()
    return sim


def wheel_cmd(left: float, right: float) -> Float64MultiArray:
    return Float64MultiArray(data=[left, right])


def answer(left: float, right: float, clock: Clock) -> Float64MultiArray:
    """A wheel_cmd that answers the step of `clock`: its layout's label names that step (the step protocol)."""
    msg = wheel_cmd(left, right)
    msg.layout.dim = [MultiArrayDimension(label=stamp_label(clock.clock.sec, clock.clock.nanosec), size=2, stride=2)]
    return msg


def test_one_command_moves_the_robot_until_the_timeout(launch, test_node):
    start_sim(launch, test_node, cmd_timeout=1.0)
    truth = test_node.collect(Odometry, 'ground_truth')
    odom = test_node.collect(Odometry, 'odom')
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: len(truth) > 5 and pub.get_subscription_count() > 0, what='sim topics')
    start = truth[-1].pose.pose.position
    pub.publish(wheel_cmd(HALF_SPEED, HALF_SPEED))
    test_node.spin_until(lambda: truth[-1].twist.twist.linear.x > 0, what='the robot to move')
    test_node.spin_until(lambda: truth[-1].twist.twist.linear.x == 0.0, what='the timeout to stop the robot')
    test_node.spin_for(0.3)
    end = truth[-1].pose.pose.position
    travelled = math.hypot(end.x - start.x, end.y - start.y)
    # 1.0 s of commands is 31.25 steps of 32 ms: 31 or 32 steps of motion at 0.0628 m/s.
    assert 31 * STEP * LINEAR_SPEED - 1e-6 <= travelled <= 32 * STEP * LINEAR_SPEED + 1e-6
    moving = [m for m in odom if m.twist.twist.linear.x > 0]
    assert moving and all(abs(m.twist.twist.linear.x - LINEAR_SPEED) < 2e-3 for m in moving)
    assert abs(odom[-1].pose.pose.position.x - (end.x - start.x)) < 2e-3  # odometry agrees when nothing slips


def test_proximity_is_eight_ranges_per_cycle_in_index_order(launch, test_node):
    start_sim(launch, test_node)
    ranges = test_node.collect(Range, 'proximity', 1000)
    test_node.spin_until(lambda: len(ranges) >= 8 * 20, what='20 sensing cycles')
    first = next(i for i, m in enumerate(ranges) if m.header.frame_id == 'ps0')
    cycles = [ranges[i:i + 8] for i in range(first, len(ranges) - 7, 8)]
    for cycle in cycles:
        assert [m.header.frame_id for m in cycle] == list(SENSOR_NAMES)
        assert len({stamp_seconds(m) for m in cycle}) == 1
    for msg in ranges:
        assert msg.radiation_type == Range.INFRARED
        assert msg.field_of_view == pytest.approx(0.1)
        assert (msg.min_range, msg.max_range) == (0.0, pytest.approx(0.07))
        assert msg.range == math.inf or 0.0 <= msg.range <= 0.07
    stamps = [stamp_seconds(c[0]) for c in cycles]
    assert all(b - a == pytest.approx(STEP, abs=1e-6) for a, b in zip(stamps, stamps[1:]))


def test_clock_advances_one_time_step_per_step(launch, test_node):
    start_sim(launch, test_node, real_time_factor=0.0)
    clocks = test_node.collect(Clock, '/clock', 100)
    test_node.spin_until(lambda: len(clocks) >= 200, what='200 /clock messages')
    times = [c.clock.sec + c.clock.nanosec * 1e-9 for c in clocks]
    assert all(later > earlier for earlier, later in zip(times, times[1:]))
    assert min(b - a for a, b in zip(times, times[1:])) == pytest.approx(STEP, abs=1e-6)


def test_a_late_clock_reader_of_the_kept_profile_gets_the_last_tick(launch, test_node):
    """`bringup`'s monitor reads /clock as CLOCK_KEPT: a simulator that matched it only after its last step (a
    500-robot swarm's, whose graph lags by tens of seconds) still delivers the tick that ends the run; with a
    volatile /clock bringup waited for ever. Here the reader comes after the simulator paused itself."""
    from epuck_ros.ros.qos import CLOCK_KEPT
    start_sim(launch, test_node, real_time_factor=0.0, pause_at=0.32)
    parameters = test_node.node.create_client(GetParameters, '/sim/get_parameters')
    test_node.spin_until(parameters.service_is_ready, what='the simulator\'s parameter service')

    def is_paused() -> bool:
        future = parameters.call_async(GetParameters.Request(names=['paused']))
        test_node.spin_until(future.done, what='the paused parameter')
        return future.result().values[0].bool_value

    test_node.spin_until(is_paused, timeout=60, what='the simulator to pause itself at 0.32 s')
    late = test_node.collect(Clock, '/clock', CLOCK_KEPT)
    test_node.spin_until(lambda: any(abs(c.clock.sec + c.clock.nanosec * 1e-9 - 0.32) < 1e-6 for c in late),
                         what='the last tick, kept')


def test_reset_puts_the_robot_back_and_zeroes_odometry(launch, test_node):
    start_sim(launch, test_node, real_time_factor=10.0)
    # Every step's message kept (the sim runs at 10x, a loaded test node may fall a few hundred behind)
    truth = test_node.collect(Odometry, 'ground_truth', EVERY_MESSAGE)
    odom = test_node.collect(Odometry, 'odom', EVERY_MESSAGE)
    joints = test_node.collect(JointState, 'joint_states', EVERY_MESSAGE)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: truth and pub.get_subscription_count() > 0, what='sim topics')
    home = truth[-1].pose.pose.position

    def moving() -> list:   # 2 cm out, the wheels still turning (cmd_timeout stops them 0.5 simulated s on)
        return [msg for msg in odom if msg.pose.pose.position.x > 0.02 and msg.twist.twist.linear.x > 0.0]

    pub.publish(wheel_cmd(HALF_SPEED, 0.3 * MAX_WHEEL_SPEED))
    test_node.spin_until(moving, what='the robot to move')
    moved = stamp_seconds(moving()[0])   # the joint states of that very step
    test_node.spin_until(lambda: any(stamp_seconds(msg) == moved for msg in joints), what='joint_states of that step')
    then = next(msg for msg in joints if stamp_seconds(msg) == moved)
    assert then.position[0] > 0.5 and then.velocity[0] == pytest.approx(HALF_SPEED)
    client = test_node.node.create_client(Empty, 'reset')
    assert client.wait_for_service(timeout_sec=10.0)
    future = client.call_async(Empty.Request())
    test_node.spin_until(future.done, what='the reset service')
    # messages of steps before the reset may still be on their way: wait for the first one at home
    test_node.spin_until(lambda: math.hypot(truth[-1].pose.pose.position.x - home.x,
                                            truth[-1].pose.pose.position.y - home.y) < 1e-9, what='the robot home')
    settled = stamp_seconds(truth[-1])
    test_node.spin_until(lambda: min(stamp_seconds(odom[-1]), stamp_seconds(joints[-1])) >= settled,
                         what='odom and joint_states after reset')
    assert truth[-1].twist.twist.linear.x == 0.0  # the command went with the reset
    assert odom[-1].pose.pose.position.x == pytest.approx(0.0, abs=1e-9)
    assert joints[-1].position == pytest.approx([0.0, 0.0])


def test_bad_commands_are_refused_and_the_simulation_goes_on(launch, test_node):
    log = test_node.watch_log()
    sim = start_sim(launch, test_node)
    clocks = test_node.collect(Clock, '/clock', 100)
    truth = test_node.collect(Odometry, 'ground_truth')
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: clocks and pub.get_subscription_count() > 0, what='sim topics')
    pub.publish(wheel_cmd(math.nan, 1.0))
    test_node.wait_for_log(log, 'wheel_cmd refused')
    pub.publish(Float64MultiArray(data=[1.0, 2.0, 3.0]))
    test_node.wait_for_log(log, 'got 3 values')
    count = len(clocks)
    test_node.spin_until(lambda: len(clocks) > count + 20, what='the clock to go on')
    assert all(m.twist.twist.linear.x == 0.0 for m in truth)
    assert sim.proc.poll() is None


def test_a_flood_of_malformed_wheel_cmd_bytes_costs_a_throttled_warning_and_lockstep_goes_on(launch, test_node):
    """Before: rclpy's C deserialiser printed a line to stderr for each undecodable message, 200 for 200."""
    sim = start_sim(launch, test_node, lockstep=True, lockstep_timeout=30.0, real_time_factor=0.0)
    clocks = test_node.collect(Clock, '/clock', 100)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 200)
    test_node.spin_until(lambda: pub.get_subscription_count() > 0 and test_node.node.count_publishers('/clock'),
                         what='the sim to be discovered')
    test_node.spin_until(lambda: clocks, what='the first step')
    bad = bytearray(serialize_message(wheel_cmd(1.0, 1.0)))
    bad[12:16] = (1000).to_bytes(4, 'little')   # a sequence of 1,000 numbers in a buffer of 2
    started = time.monotonic()
    for _ in range(200):
        pub.publish(bytes(bad))   # bytes go out as the serialised message
    seen = len(clocks)
    pub.publish(answer(1.0, 1.0, clocks[-1]))   # after the bad ones on the same writer: it answers the step
    test_node.spin_until(lambda: len(clocks) > seen, timeout=60.0, what='the step answering the good command')
    elapsed = time.monotonic() - started
    lines = [line for line in sim.output().splitlines() if 'wheel_cmd refused' in line or 'buffer' in line]
    assert any('no Float64MultiArray' in line for line in lines)
    # one warning per WARN_PERIOD at most: the bound grows only if the machine took that long to read 200 messages
    assert len(lines) <= max(3, 1 + math.ceil(elapsed / WARN_PERIOD)), '\n'.join(lines)
    assert sim.proc.poll() is None


FORGED_LABELS = ['stamp=\u00b2.000000000', 'stamp=1.' + '\u00b2' * 9, 'stamp=\u0663.032000000',
                 'stamp=1' + '0' * 400 + '.000000000']
"""Labels that killed `sim` (a ValueError from int() on Unicode digits, an OverflowError writing the refusal of a step
10^400 s ahead) and `avoid` (the same labels on ir_raw)."""


def test_forged_step_labels_kill_no_node_and_lockstep_goes_on(launch, test_node):
    sim = start_sim(launch, test_node, lockstep=True, real_time_factor=0.0)
    avoid = launch('avoid', *ros_args({'use_sim_time': True}))
    clocks = test_node.collect(Clock, '/clock', 100)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    forged_ir = test_node.node.create_publisher(Float64MultiArray, 'ir_raw', 10)
    test_node.spin_until(lambda: clocks and pub.get_subscription_count() > 0 and forged_ir.get_subscription_count() > 0,
                         what='the sim and avoid to be discovered')
    for label in FORGED_LABELS:
        forged = wheel_cmd(1.0, 1.0)
        forged.layout.dim = [MultiArrayDimension(label=label, size=2, stride=2)]
        pub.publish(forged)
        forged_ir.publish(Float64MultiArray(layout=forged.layout, data=[100.0] * 8))
    seen = len(clocks)
    test_node.spin_until(lambda: len(clocks) > seen + 10, what='steps after the forged labels')
    assert sim.proc.poll() is None and avoid.proc.poll() is None, sim.output() + avoid.output()


def test_world_and_collision_count_are_latched(launch, test_node):
    start_sim(launch, test_node)
    worlds = test_node.collect(String, 'world', LATCHED)
    collisions = test_node.collect(UInt32, 'collisions', LATCHED)
    test_node.spin_until(lambda: worlds and collisions, what='latched world and collisions')
    assert 'arena' in worlds[0].data
    assert collisions[0].data == 0


@pytest.mark.parametrize('param, expected', [
    ('time_step:=-1.0', 'time_step'),
    ('real_time_factor:=fast', 'real_time_factor'),
    ('world:=/no/such/world.yaml', '/no/such/world.yaml'),
    ('frame_prefix:=1bad', 'frame_prefix'),
])
def test_bad_parameters_are_refused_at_start(launch, param, expected):
    sim = launch('sim', '--ros-args', '-p', param)
    assert sim.proc.wait(timeout=20) != 0
    assert expected in sim.output()


def test_malformed_world_file_names_the_field(launch, tmp_path: Path):
    world = tmp_path / 'bad.yaml'
    world.write_text('boxes:\n  - position: [0.3, 0.2]\n    size: [0.1, -0.1]\n')
    sim = launch('sim', *ros_args({'world': str(world)}))
    assert sim.proc.wait(timeout=20) == 2
    assert 'boxes[0].size' in sim.output() and str(world) in sim.output()


def test_lockstep_pairs_each_answer_with_the_step_it_names(launch, test_node):
    """One step per answer naming the current step; a repeat of it, or one naming a step not reached, takes no step;
    the run is reproducible (lockstep_status) until a command that names no step makes the robot's controller
    free: from then on the simulation goes on without waiting for it."""
    start_sim(launch, test_node, lockstep=True, real_time_factor=0.0)
    clocks = test_node.collect(Clock, '/clock', 1000)
    statuses = test_node.collect(DiagnosticStatus, 'lockstep_status', LATCHED)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    # The first step goes out once the sim matched our publisher (lockstep_controllers 1), and again every second
    # until answered (we may have subscribed to /clock after it).
    test_node.spin_until(lambda: clocks, what='the first step')
    steps_per_answer = []
    for _ in range(5):
        seen, step = len(clocks), clocks[-1]
        pub.publish(answer(1.0, 1.0, step))
        pub.publish(answer(1.0, 1.0, step))   # a repeat: dropped
        test_node.spin_until(lambda: len(clocks) > seen, what='the step answering the command')
        test_node.spin_for(0.3)  # without another answer, no further step comes
        steps_per_answer.append(len({(c.clock.sec, c.clock.nanosec) for c in clocks[seen:]}))
    assert steps_per_answer == [1] * 5
    times = sorted({c.clock.sec + c.clock.nanosec * 1e-9 for c in clocks})
    assert [b - a for a, b in zip(times, times[1:])] == pytest.approx([STEP] * (len(times) - 1), abs=1e-9)
    future = Clock()
    future.clock.sec = clocks[-1].clock.sec + 10
    seen = len(clocks)
    pub.publish(answer(1.0, 1.0, future))
    test_node.spin_for(0.5)
    assert len(clocks) == seen   # an answer naming a step not reached answers nothing
    test_node.spin_until(lambda: statuses, what='lockstep_status')
    assert statuses[-1].level == DiagnosticStatus.OK and 'reproducible: every step' in statuses[-1].message
    pub.publish(wheel_cmd(0.5, 0.5))   # names no step, beside named answers: a teleop, say; it answers nothing
    test_node.spin_until(lambda: statuses[-1].level == DiagnosticStatus.WARN, what='the run said not reproducible')
    assert 'not reproducible: a command that names no step drove epuck beside its lockstep controller' in \
        statuses[-1].message
    assert len(clocks) == seen
    pub.publish(answer(1.0, 1.0, clocks[-1]))
    test_node.spin_until(lambda: len(clocks) > seen, what='the step answering the next named answer')


def test_a_controller_whose_commands_name_no_step_is_not_waited_for_and_the_run_says_so(launch, test_node):
    """A timer or a joystick on plain wheel_cmd (or Twist): recognised by what it sends, not by how late."""
    start_sim(launch, test_node, lockstep=True, real_time_factor=0.0)
    clocks = test_node.collect(Clock, '/clock', 1000)
    statuses = test_node.collect(DiagnosticStatus, 'lockstep_status', LATCHED)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: clocks, what='the first step')
    seen = len(clocks)
    pub.publish(wheel_cmd(1.0, 1.0))
    test_node.spin_until(lambda: len(clocks) > seen + 20, what='steps without waiting for the free controller')
    test_node.spin_until(lambda: statuses and statuses[-1].level == DiagnosticStatus.WARN,
                         what='the run said not reproducible')
    assert 'not reproducible: the controller of epuck sends commands that name no step' in statuses[-1].message


def test_lockstep_takes_no_step_before_it_sees_the_controllers_it_was_told_of(launch, test_node):
    """`lockstep_controllers` 1: no step while nobody commands (without it, one every lockstep_timeout), and it
    says so; once it matches a wheel_cmd publisher, it steps."""
    log = test_node.watch_log()
    start_sim(launch, test_node, lockstep=True, lockstep_timeout=0.05, real_time_factor=0.0, lockstep_controllers=1)
    clocks = test_node.collect(Clock, '/clock', 100)
    test_node.wait_for_log(log, 'lockstep: waiting for 1 controller before the first step')
    assert clocks == []
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: clocks, what='the first step, once the sim has matched our wheel_cmd publisher')
    pub.publish(wheel_cmd(1.0, 1.0))
    test_node.spin_until(lambda: len(clocks) > 1, what='the step answering the command')


def test_help_describes_every_parameter_and_starts_nothing(launch):
    sim = launch('sim', '--help')
    assert sim.proc.wait(timeout=20) == 0
    output = sim.output()
    for name in ('real_time_factor', 'robots', 'lockstep', 'cmd_timeout', 'seed'):
        assert f'\n  {name} ' in output
    assert 'example:' in output and 'ir_raw' in output
    assert 'sim ready' not in output


@pytest.mark.parametrize('param, expected', [
    ('seeed:=3', "unknown parameter 'seeed' (did you mean seed?)"),
    ('real_time_factr:=0', 'did you mean real_time_factor?'),
    ('seed:=abc', 'seed: expected an integer'),
    ('robots:=-1', 'robots: -1 is out of range'),
    ('cmd_timeout:=', 'cmd_timeout: empty value'),
])
def test_unknown_or_invalid_parameters_are_named_and_refused(launch, param, expected):
    sim = launch('sim', '--ros-args', '-p', param)
    assert sim.proc.wait(timeout=20) == 2
    assert expected in sim.output() and 'Traceback' not in sim.output()


def test_integers_are_accepted_for_float_parameters_and_use_sim_time_is_ignored(launch, test_node):
    log = test_node.watch_log()
    launch('sim', '--ros-args', '-p', 'real_time_factor:=0', '-p', 'cmd_timeout:=2', '-p', 'use_sim_time:=true')
    test_node.wait_for_log(log, 'use_sim_time ignored')
    test_node.wait_for_log(log, 'real-time factor max')
    client = test_node.node.create_client(GetParameters, '/sim/get_parameters')
    assert client.wait_for_service(timeout_sec=20.0)
    future = client.call_async(GetParameters.Request(names=['real_time_factor', 'cmd_timeout', 'use_sim_time']))
    test_node.spin_until(future.done, what='the parameters')
    rtf, timeout, sim_time = future.result().values
    assert (rtf.type, rtf.double_value) == (ParameterType.PARAMETER_DOUBLE, 0.0)
    assert (timeout.type, timeout.double_value) == (ParameterType.PARAMETER_DOUBLE, 2.0)
    assert sim_time.bool_value is False
    # the clock source does not listen to its own /clock
    subscribers = test_node.node.get_subscriptions_info_by_topic('/clock')
    assert not [s for s in subscribers if s.node_name == 'sim']
    # ... nor can it be made to later: the set is refused with its reason
    setter = test_node.node.create_client(SetParameters, '/sim/set_parameters')
    assert setter.wait_for_service(timeout_sec=20.0)
    on = ParameterMsg(name='use_sim_time', value=ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=True))
    future = setter.call_async(SetParameters.Request(parameters=[on]))
    test_node.spin_until(future.done, what='the answer to use_sim_time:=true')
    result, = future.result().results
    assert not result.successful and 'source of /clock' in result.reason


def test_a_second_simulator_on_the_domain_is_refused(launch, test_node):
    first = start_sim(launch, test_node)
    clocks = test_node.collect(Clock, '/clock', 100)
    test_node.spin_until(lambda: clocks, what='the first simulator')
    second = launch('sim', *ros_args({'noise': False}))
    assert second.proc.wait(timeout=30) == 2
    assert 'another simulator runs on ROS domain' in second.output() and 'use another ROS_DOMAIN_ID' in \
        second.output()
    assert 'sim ready' not in second.output()   # issue 33 item 14: it said ready, then refused
    assert 'sim ready' in first.output()
    count = len(clocks)
    test_node.spin_until(lambda: len(clocks) > count + 5, what='the first simulator to go on')
    assert first.proc.poll() is None


def test_cmd_vel_nan_is_refused_and_huge_speeds_clamp(launch, test_node):
    log = test_node.watch_log()
    sim = start_sim(launch, test_node, real_time_factor=10.0)
    joints = test_node.collect(JointState, 'joint_states', 1000)
    pub = test_node.node.create_publisher(Twist, 'cmd_vel', 10)
    test_node.spin_until(lambda: joints and pub.get_subscription_count() > 0, what='sim topics')
    pub.publish(Twist(linear=Vector3(x=math.nan)))
    test_node.wait_for_log(log, 'cmd_vel refused')
    pub.publish(Twist(linear=Vector3(x=1e308)))
    test_node.spin_until(lambda: joints[-1].velocity[0] > 0, what='the robot to drive')
    assert list(joints[-1].velocity) == [MAX_WHEEL_SPEED, MAX_WHEEL_SPEED]
    assert sim.proc.poll() is None


def test_repeated_timeouts_are_logged_once_then_counted(launch, test_node):
    sim = start_sim(launch, test_node, real_time_factor=10.0, cmd_timeout=0.1)
    truth = test_node.collect(Odometry, 'ground_truth', 1000)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: truth and pub.get_subscription_count() > 0, what='sim topics')
    for _ in range(3):
        pub.publish(wheel_cmd(1.0, 1.0))
        test_node.spin_until(lambda: truth[-1].twist.twist.linear.x > 0, what='the robot to move')
        test_node.spin_until(lambda: truth[-1].twist.twist.linear.x == 0.0, what='the timeout')
    assert sim.stop() == 0  # the first SIGINT ends it cleanly, after a client came and went
    output = sim.log_path.read_text()
    assert output.count('no command for 0.1 s') == 1
    assert 'command time-out: wheels stopped 2 more times (epuck 2)' in output


@pytest.mark.parametrize('prefix', ['r1/', 'r1'])   # a prefix gets its slash: r1/odom, not r1odom
def test_one_robot_keeps_its_names_with_a_frame_prefix_and_the_markers_are_latched(launch, test_node, prefix):
    start_sim(launch, test_node, frame_prefix=prefix)
    odom = test_node.collect(Odometry, 'odom')
    truth = test_node.collect(Odometry, 'ground_truth')
    ranges = test_node.collect(Range, 'proximity', 1000)
    markers = test_node.collect(MarkerArray, 'world_markers', LATCHED)
    test_node.spin_until(lambda: odom and truth and len(ranges) >= 8 and markers, what='odom, ranges, markers')
    assert (odom[0].header.frame_id, odom[0].child_frame_id) == ('r1/odom', 'r1/base_link')
    assert (truth[0].header.frame_id, truth[0].child_frame_id) == ('r1/world', 'r1/base_link')
    assert {m.header.frame_id for m in ranges} == {f'r1/ps{i}' for i in range(8)}
    assert markers[0].markers and {m.header.frame_id for m in markers[0].markers} == {'r1/world'}


@pytest.mark.parametrize('args, mode', [
    ([], 'ASYNCHRONOUS'),
    (['--ros-args', '-p', 'lockstep:=true'], 'SYNCHRONOUS'),
    (['--ros-args', '-p', 'lockstep:=true', '--param', 'lockstep:=false'], 'ASYNCHRONOUS'),
    (['--ros-args', '-p', 'seed:=3', '-p', 'lockstep:=True'], 'SYNCHRONOUS'),
])
def test_lockstep_on_the_command_line_publishes_synchronously(args, mode):
    assert publication_mode(['sim', *args]) == mode


def test_another_middleware_gets_one_warning(monkeypatch):
    import rclpy

    from epuck_ros.ros.dds_profile import FAST_DDS, warn_if_not_fast_dds
    said = []

    class Logger:
        def warning(self, text: str) -> None:
            said.append(text)
    assert rclpy.get_rmw_implementation_identifier() == FAST_DDS   # what this package is measured with
    warn_if_not_fast_dds(Logger())
    assert said == []
    monkeypatch.setattr(rclpy, 'get_rmw_implementation_identifier', lambda: 'rmw_cyclonedds_cpp')
    warn_if_not_fast_dds(Logger())
    assert len(said) == 1 and 'middleware rmw_cyclonedds_cpp: epuck_ros is tuned for rmw_fastrtps_cpp' in said[0]


def test_the_no_local_profile_is_the_package_profile_without_local_matching(monkeypatch):
    """fastdds_no_local_profiles.xml is fastdds_profiles.xml plus fastdds.ignore_local_endpoints (the file says why):
    any other difference would make the simulator's (and the behaviours') DDS behave unlike its peers'. It is theirs
    unless the user chose a profile; the package's, which `bringup` passes to its children, is no choice of the
    user's."""
    import os
    import xml.etree.ElementTree as ET

    from epuck_ros.ros.dds_profile import (NO_LOCAL_PROFILES_FILE, PROFILES_FILE, PROFILES_VARIABLE,
                                           use_no_local_profile)

    def settings(path: Path) -> list[tuple[str, str]]:
        tree = ET.parse(path)
        return [(element.tag, (element.text or '').strip()) for element in tree.iter()] + \
            [(element.tag, str(sorted(element.attrib.items()))) for element in tree.iter() if element.attrib]

    ignore = [('{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}' + tag, text) for tag, text in [
        ('propertiesPolicy', ''), ('properties', ''), ('property', ''), ('name', 'fastdds.ignore_local_endpoints'),
        ('value', 'true')]]
    sim = settings(NO_LOCAL_PROFILES_FILE)
    start = sim.index(ignore[0])
    assert sim[start:start + len(ignore)] == ignore
    assert sim[:start] + sim[start + len(ignore):] == settings(PROFILES_FILE)
    for chosen, used in [(None, NO_LOCAL_PROFILES_FILE), (str(PROFILES_FILE), NO_LOCAL_PROFILES_FILE),
                         ('/home/me/my_profile.xml', Path('/home/me/my_profile.xml'))]:
        if chosen is None:
            monkeypatch.delenv(PROFILES_VARIABLE, raising=False)
        else:
            monkeypatch.setenv(PROFILES_VARIABLE, chosen)
        use_no_local_profile()
        assert Path(os.environ[PROFILES_VARIABLE]) == used


def lockstep_sim(launch, test_node, **params):
    """A lockstep sim at full speed, its /clock and lockstep_status collected."""
    sim = start_sim(launch, test_node, lockstep=True, real_time_factor=0.0, **params)
    return sim, test_node.collect(Clock, '/clock', 1000), test_node.collect(DiagnosticStatus, 'lockstep_status',
                                                                            LATCHED)


@pytest.mark.parametrize('second', ['another publisher', 'the same publisher'])
def test_two_different_answers_to_one_step_break_the_run_and_name_the_publishers(launch, test_node, second):
    """Issue 33 item 3: a second process answering each step by name took a robot over, and the run was called
    reproducible: the controller's own answer was dropped as a repeat. The same answer twice is still a repeat."""
    sim, clocks, statuses = lockstep_sim(launch, test_node)
    controller = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    intruder = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10) \
        if second == 'another publisher' else controller
    test_node.spin_until(lambda: clocks and controller.get_subscription_count() and intruder.get_subscription_count(),
                         what='the first step, our publishers matched')
    step = clocks[-1]
    controller.publish(answer(1.0, 1.0, step))
    test_node.spin_until(lambda: clocks[-1].clock != step.clock, what='the step answering the command')
    controller.publish(answer(1.0, 1.0, step))   # a repeat: dropped, nothing said
    test_node.spin_for(0.3)
    assert statuses[-1].level == DiagnosticStatus.OK, statuses[-1].message
    intruder.publish(answer(-1.0, 1.0, step))
    test_node.spin_until(lambda: statuses[-1].level == DiagnosticStatus.WARN, what='the run said not reproducible')
    message = statuses[-1].message
    assert 'epuck got two different answers to t=0.032 s ([1.0, 1.0] on /wheel_cmd, then [-1.0, 1.0] on ' \
           '/wheel_cmd)' in message, message
    assert message.count(f'/{test_node.node.get_name()} on /wheel_cmd (gid ') == \
        (2 if second == 'another publisher' else 1), message
    assert sim.proc.poll() is None


def test_a_nan_answer_answers_nothing_and_the_step_waits_for_a_valid_one(launch, test_node):
    """Issue 33 item 3: a NaN answer naming the current step was taken as its answer (the robot kept its last
    command) and the controller's valid answer after it dropped as a repeat."""
    sim, clocks, statuses = lockstep_sim(launch, test_node)
    truth = test_node.collect(Odometry, 'ground_truth', EVERY_MESSAGE)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: clocks and pub.get_subscription_count(), what='the first step')
    step, seen = clocks[-1], len(clocks)
    pub.publish(answer(math.nan, 1.0, step))
    test_node.spin_for(0.5)
    assert len(clocks) == seen, 'a NaN answer took the step'
    pub.publish(answer(HALF_SPEED, HALF_SPEED, step))
    test_node.spin_until(lambda: len(clocks) > seen, what='the step answering the valid command')
    test_node.spin_until(lambda: truth and truth[-1].twist.twist.linear.x > 0, what='the valid command to drive')
    assert 'wheel_cmd refused' in sim.output()
    assert statuses[-1].level == DiagnosticStatus.OK, statuses[-1].message


def test_a_lockstep_controller_that_left_the_graph_is_waited_for_and_sent_its_step_again_when_back(launch, test_node):
    """Issue 33 item 4: a controller stopped (SIGSTOP) left the graph once DDS dropped it; its robot was then
    undriven, the run went on without it and was called reproducible. Here the publisher leaves at once: no step
    is taken without its answer, and when a controller is back it gets the step again."""
    sim, clocks, statuses = lockstep_sim(launch, test_node)
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: clocks and pub.get_subscription_count(), what='the first step')
    for _ in range(3):
        step = clocks[-1]
        pub.publish(answer(1.0, 1.0, step))
        test_node.spin_until(lambda: clocks[-1].clock != step.clock, what='the step answering the command')
    test_node.node.destroy_publisher(pub)
    waiting, seen = clocks[-1], len(clocks)
    test_node.spin_for(1.5)
    assert [c.clock for c in clocks[seen:]] in ([], [waiting.clock]), 'steps taken without the robot\'s answer'
    back = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: len(clocks) > seen and clocks[-1].clock == waiting.clock,
                         what='the step sent again once a controller is back')
    sim.wait_for_output(
        f'the controller of epuck is back on the graph: sending t={stamp_seconds_of(waiting):.3f} s again')
    back.publish(answer(1.0, 1.0, waiting))
    test_node.spin_until(lambda: clocks[-1].clock != waiting.clock, what='the step after the answer')
    assert statuses[-1].level == DiagnosticStatus.OK, statuses[-1].message
    assert sim.proc.poll() is None


def test_a_plain_twist_publisher_is_at_its_own_rate_from_the_moment_the_graph_shows_it(launch, test_node):
    """Issue 33 item 6: a node publishing Twist on cmd_vel from a timer on simulated time cannot answer before time
    moves: the first step waited FIRST_ANSWER_WAIT (10 s), sent again every second. Its type names no step: it is
    not waited for; the run breaks once its commands drive."""
    sim, clocks, statuses = lockstep_sim(launch, test_node)
    pub = test_node.node.create_publisher(Twist, 'cmd_vel', 10)
    test_node.spin_until(lambda: clocks and clocks[-1].clock.nanosec >= 500_000_000, what='half a simulated second')
    assert statuses[-1].level == DiagnosticStatus.OK, statuses[-1].message   # nothing drove
    pub.publish(Twist(linear=Vector3(x=0.05)))
    test_node.spin_until(lambda: statuses[-1].level == DiagnosticStatus.WARN, what='the run said not reproducible')
    assert 'the controller of epuck sends commands that name no step' in statuses[-1].message
    assert 'sending it again' not in sim.output() and 'first step within' not in sim.output()


def test_a_controller_declared_at_its_own_rate_is_not_waited_for(launch, test_node):
    """Issue 33 item 6: an unlabelled wheel_cmd timer cannot be told from a lockstep controller by its type: it
    declares itself (epuck_ros/lockstep.py, DECLARATION_TOPIC) and is not waited for. A declaration that is no
    declaration costs a line."""
    sim, clocks, statuses = lockstep_sim(launch, test_node)
    nonsense = test_node.node.create_publisher(String, DECLARATION_TOPIC, LATCHED)   # a writer each: both kept
    nonsense.publish(String(data='whatever /wheel_cmd'))
    declarations = test_node.node.create_publisher(String, DECLARATION_TOPIC, LATCHED)
    declarations.publish(String(data=declaration(Controller.OWN_RATE, ['/wheel_cmd'])))
    pub = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
    test_node.spin_until(lambda: clocks and clocks[-1].clock.nanosec >= 500_000_000, what='half a simulated second')
    assert 'sending it again' not in sim.output()
    pub.publish(wheel_cmd(1.0, 1.0))
    test_node.spin_until(lambda: statuses[-1].level == DiagnosticStatus.WARN, what='the run said not reproducible')
    assert 'the controller of epuck sends commands that name no step' in statuses[-1].message
    assert f'a declaration on {DECLARATION_TOPIC} refused: it must start with lockstep or own_rate' in sim.output()


def test_the_behaviours_and_the_webots_link_declare_lockstep(launch, test_node):
    declared = test_node.collect(String, DECLARATION_TOPIC, DECLARATIONS_READ)
    launch('forward', *ros_args({'use_sim_time': True}))
    launch('spin', '--ros-args', '-r', '__ns:=/epuck2')   # on its own clock: not in lockstep
    link = SimLink('link_under_test', 'epuck3', lambda: True)
    try:
        test_node.spin_until(lambda: len(declared) >= 3, what='three declarations')
    finally:
        link.node.destroy_node()
    assert sorted(message.data for message in declared) == [
        'lockstep /epuck3/wheel_cmd', 'lockstep /wheel_cmd', 'own_rate /epuck2/wheel_cmd']


def test_a_behaviour_that_ends_says_goodbye_and_a_lockstep_run_goes_on_without_it(launch, test_node):
    """A controller that left without a word is waited for (item 4); one that ends on purpose (Ctrl-C) says so
    first, and the simulation goes on without it."""
    sim, clocks, _ = lockstep_sim(launch, test_node)
    forward = launch('forward', *ros_args({'use_sim_time': True}))
    test_node.spin_until(lambda: clocks and clocks[-1].clock.sec >= 1, timeout=60, what='a second driven by forward')
    forward.proc.send_signal(signal.SIGINT)
    test_node.spin_until(lambda: forward.proc.poll() is not None, what='forward to end')
    sim.wait_for_output('lockstep: the controller of epuck left, declared at its own rate: no longer waited for')
    seen = len(clocks)
    test_node.spin_until(lambda: len(clocks) > seen + 10, what='steps without it')
