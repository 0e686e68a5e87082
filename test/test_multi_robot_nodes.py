"""Several robots in one `sim` process, each driven by its own client over DDS, in lockstep (no timing assumed)."""
from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ros_args
from geometry_msgs.msg import Twist, TwistStamped, Vector3
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Imu, JointState, Range
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String, UInt32
from std_srvs.srv import Trigger

from epuck_ros.conversions import stamp_from_label, stamp_label
from epuck_ros.lockstep import DECLARATION_TOPIC, Controller, declaration
from epuck_ros.nodes.sim_node import DESTROY_UP_TO
from epuck_ros.ros.ack_window import history_steps
from epuck_ros.ros.on_demand import TOPICS_ON_DEMAND_FROM, OnDemand
from epuck_ros.ros.sense_ports import SENSE_TOPICS_ON_DEMAND_FROM

STEP = 0.032
HALF_SPEED = 3.14
WHEEL_RADIUS, BODY_RADIUS = 0.02, 0.037
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
EVERY_STEP = 10000
"""Subscription depth that keeps every message of a test run."""
ROBOT_TOPICS = ('cmd_vel', 'wheel_cmd', 'odom', 'ground_truth', 'proximity', 'joint_states', 'collisions', 'ir_raw')
# Webots E-puckDistanceSensor lookupTable (distance m, raw value), from the course's e-puck PROTO.
IR_TABLE = [(0.0, 4095.0), (0.005, 2133.33), (0.01, 1465.73), (0.015, 601.46), (0.02, 383.84), (0.03, 234.93),
            (0.04, 158.03), (0.05, 120.0), (0.06, 104.09), (0.07, 67.19)]
PS0 = (0.030, -0.010, -0.3008)
"""ps0's pose on the body (x, y, yaw), from the E-puck PROTO."""


def write_world(tmp_path: Path, robots: list[tuple[str, float, float, float]], boxes: bool = False) -> str:
    world = {'arena': {'size': [1.0, 1.0]},
             'robots': [{'name': name, 'start': [x, y, yaw]} for name, x, y, yaw in robots]}
    if boxes:
        world['boxes'] = [{'position': [0.0, 0.0], 'size': [0.15, 0.15]}]
    path = tmp_path / 'robots.yaml'
    path.write_text(yaml.safe_dump(world))
    return str(path)


def seconds(stamp: object) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def pose(msg: Odometry) -> tuple[float, float, float]:
    q = msg.pose.pose.orientation
    return msg.pose.pose.position.x, msg.pose.pose.position.y, 2.0 * math.atan2(q.z, q.w)


def set_parameter(test_node, name: str, value: ParameterValue) -> None:
    """Set one of the sim's parameters; the request is sent again if no answer comes (setting is idempotent, and
    on a loaded machine the first request of a new client is occasionally lost before the service matched it)."""
    client = test_node.node.create_client(SetParameters, '/sim/set_parameters')
    assert client.wait_for_service(timeout_sec=20.0)
    request = SetParameters.Request(parameters=[ParameterMsg(name=name, value=value)])
    for _ in range(6):
        future = client.call_async(request)
        try:
            test_node.spin_until(future.done, timeout=5.0, what=f'setting {name}')
            break
        except AssertionError:
            client.remove_pending_request(future)
    assert future.done(), f'no answer to setting {name}'
    assert future.result().results[0].successful, future.result().results[0].reason
    test_node.node.destroy_client(client)


def boolean(value: bool) -> ParameterValue:
    return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)


def subscribe(test_node, msg_type: type, topic: str, qos: object = EVERY_STEP) -> tuple[list, object]:
    """The list received messages go to, and the subscription (to see when it matched the sim)."""
    received: list = []
    return received, test_node.node.create_subscription(msg_type, topic, received.append, qos)


class LockstepClients:
    """Answers each step of a lockstep sim for some robots, by the step protocol: once every robot's `ir_raw` of that
    step is in (paired by the step its label names), `command(robot, step, ir_raw)` gives the message to publish on
    that robot's topic (None: no answer), which is sent naming the step (a labelled wheel_cmd; a Twist goes as a
    TwistStamped: the sim runs with cmd_vel_stamped)."""

    def __init__(self, test_node, names: list[str], topics: dict[str, tuple[type, str]],
                 command: Callable[[str, int, list[float]], object]) -> None:
        self.node = test_node.node
        self.clocks: list[float] = []
        self.raw: dict[str, list[list[float]]] = {name: [] for name in names}
        self._raw_by_step: dict[str, dict[tuple[int, int], list[float]]] = {name: {} for name in names}
        self.truth: dict[str, list[Odometry]] = {name: [] for name in names}
        self.publishers = {name: self.node.create_publisher(TwistStamped if msg_type is Twist else msg_type,
                                                            f'/{name}/{topic}', 10)
                           for name, (msg_type, topic) in topics.items()}
        self._command = command
        self.answered: list[tuple[int, int]] = []
        self._subscriptions = [self.node.create_subscription(Clock, '/clock', self._on_clock, EVERY_STEP)]
        for name in names:
            self._subscriptions += [
                self.node.create_subscription(Float64MultiArray, f'/{name}/ir_raw',
                                              lambda msg, name=name: self._on_raw(name, msg), EVERY_STEP),
                self.node.create_subscription(Odometry, f'/{name}/ground_truth', self.truth[name].append, EVERY_STEP)]

    def ready(self) -> bool:
        """Every command publisher and every subscription matched the sim."""
        return all(pub.get_subscription_count() for pub in self.publishers.values()) and \
            all(sub.get_publisher_count() for sub in self._subscriptions)

    def _on_clock(self, msg: Clock) -> None:
        self.clocks.append(seconds(msg.clock))

    def _on_raw(self, name: str, msg: Float64MultiArray) -> None:
        step = stamp_from_label(msg.layout.dim[0].label)
        if step in self._raw_by_step[name] or (self.answered and step <= self.answered[-1]):
            return   # the first step sent again
        self._raw_by_step[name][step] = list(msg.data)
        self.raw[name].append(list(msg.data))
        if all(step in raws for raws in self._raw_by_step.values()):
            self._answer(step)

    def _answer(self, step: tuple[int, int]) -> None:
        index = len(self.answered)
        for name, publisher in list(self.publishers.items()):
            msg = self._command(name, index, self._raw_by_step[name][step])
            if isinstance(msg, Float64MultiArray):
                msg.layout.dim = [MultiArrayDimension(label=stamp_label(*step), size=len(msg.data),
                                                      stride=len(msg.data))]
            elif isinstance(msg, Twist):
                stamped = TwistStamped(twist=msg)
                stamped.header.stamp.sec, stamped.header.stamp.nanosec = step
                msg = stamped
            if msg is not None:
                publisher.publish(msg)
        self.answered.append(step)


def start_lockstep_sim(launch, test_node, world: str, **params):
    """A paused lockstep sim; `run` resumes it once the clients are connected, so every step is seen."""
    sim = launch('sim', *ros_args({'world': world, 'lockstep': True, 'paused': True, 'cmd_vel_stamped': True,
                                   'real_time_factor': 0, 'noise': False, **params}))
    test_node.wait_for_simulator()
    return sim


def run(test_node, clients: LockstepClients, steps: int) -> None:
    test_node.spin_until(clients.ready, what='the clients and the sim to match')
    # Matched as the clients see it; the sim's first step waits until it has matched them too.
    set_parameter(test_node, 'lockstep_controllers',
                  ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=len(clients.publishers)))
    set_parameter(test_node, 'paused', boolean(False))
    test_node.spin_until(lambda: len(clients.clocks) >= steps and
                         all(len(t) >= steps for t in clients.truth.values()), timeout=120, what=f'{steps} steps')


def test_each_robot_follows_its_own_client_and_times_out_alone(launch, test_node, tmp_path):
    world = write_world(tmp_path, [('epuck0', -0.3, 0.3, 0.0), ('epuck1', 0.2, -0.3, 0.0), ('epuck2', 0.3, 0.3, 1.0)])
    sim = start_lockstep_sim(launch, test_node, world, cmd_timeout=0.3)
    last_wheel_command = 30

    def command(name: str, step: int, raw: list[float]) -> object:
        if name == 'epuck1':
            return Twist(angular=Vector3(z=1.0))
        if step == last_wheel_command:  # epuck0's client goes away: epuck0 times out, epuck1 goes on
            # Its goodbye first: a lockstep controller that left without one is waited for (issue 33 item 4).
            goodbye.publish(String(data=declaration(Controller.OWN_RATE, ['/epuck0/wheel_cmd'])))
            test_node.node.destroy_publisher(clients.publishers.pop('epuck0'))
            return None
        return Float64MultiArray(data=[HALF_SPEED, HALF_SPEED])

    goodbye = test_node.node.create_publisher(String, DECLARATION_TOPIC, LATCHED)
    names = ['epuck0', 'epuck1', 'epuck2']
    clients = LockstepClients(test_node, names, {'epuck0': (Float64MultiArray, 'wheel_cmd'),
                                                 'epuck1': (Twist, 'cmd_vel')}, command)
    odom1 = test_node.collect(Odometry, '/epuck1/odom', EVERY_STEP)
    ranges1 = test_node.collect(Range, '/epuck1/proximity', EVERY_STEP)
    joints1 = test_node.collect(JointState, '/epuck1/joint_states', EVERY_STEP)
    run(test_node, clients, 80)

    truth = {name: clients.truth[name][:80] for name in names}
    assert [seconds(m.header.stamp) for m in truth['epuck0']] == pytest.approx([STEP * (k + 1) for k in range(80)])
    # epuck0: straight ahead at 0.0628 m/s from the first answered step until cmd_timeout after its last command
    x0 = [pose(m)[0] for m in truth['epuck0']]
    moving = [k for k in range(1, 80) if x0[k] - x0[k - 1] > 1e-9]
    per_step = HALF_SPEED * WHEEL_RADIUS * STEP
    assert all(x0[k] - x0[k - 1] == pytest.approx(per_step, abs=1e-9) for k in moving)
    # The answer to step k (sent at its time, (k + 1) steps) drives step k + 1; the last one answered step 29.
    last_command_time = STEP * last_wheel_command
    stopped_at = min(k for k in range(80) if STEP * k - last_command_time > 0.3)
    assert moving == list(range(1, stopped_at))
    assert all(pose(m)[1] == pytest.approx(0.3, abs=1e-12) for m in truth['epuck0'])
    assert truth['epuck0'][-1].twist.twist.linear.x == 0.0
    # epuck1: turns on the spot at 1 rad/s for as long as it is answered (every step)
    x1, y1, yaw1 = zip(*(pose(m) for m in truth['epuck1']))
    assert max(map(abs, np.diff(x1))) < 1e-12 and max(map(abs, np.diff(y1))) < 1e-12
    assert truth['epuck1'][-1].twist.twist.angular.z == pytest.approx(1.0)
    assert yaw1[-1] - yaw1[0] == pytest.approx(1.0 * STEP * 79, abs=1e-6)
    # epuck2: nobody drives it, it does not move and does not hold the others up
    assert all(pose(m) == pytest.approx((0.3, 0.3, 1.0), abs=1e-12) for m in truth['epuck2'])
    # each robot's frames and topics under its name; ground truth in the shared world frame
    assert (truth['epuck1'][0].header.frame_id, truth['epuck1'][0].child_frame_id) == ('world', 'epuck1/base_link')
    assert (odom1[0].header.frame_id, odom1[0].child_frame_id) == ('epuck1/odom', 'epuck1/base_link')
    assert [m.header.frame_id for m in ranges1[:8]] == [f'epuck1/ps{i}' for i in range(8)]
    assert joints1[-1].velocity[1] - joints1[-1].velocity[0] == pytest.approx(2 * 1.0 * 0.026 / WHEEL_RADIUS)
    topics = {name for name, _ in test_node.node.get_topic_names_and_types()}
    assert {f'/{name}/{topic}' for name in names for topic in ROBOT_TOPICS} <= topics
    assert not {f'/{topic}' for topic in ROBOT_TOPICS} & topics
    assert {'/clock', '/world', '/world_markers'} <= topics
    # the timeout is logged once, for epuck0 only
    output = sim.output()
    assert output.count('epuck0: no command for 0.3 s') == 1
    assert 'epuck1: no command' not in output and 'epuck2: no command' not in output


def test_lockstep_runs_of_three_reactive_robots_are_identical(launch, test_node, tmp_path):
    """Noise on, robots that react to their own ir_raw and meet each other and a box: the same seed, the same run."""
    world = write_world(tmp_path, [('a', -0.3, 0.05, 0.0), ('b', 0.0, 0.3, -1.5), ('c', 0.3, -0.2, 2.5)], boxes=True)

    def braitenberg(name: str, step: int, raw: list[float]) -> Float64MultiArray:
        left, right = sum(raw[5:8]), sum(raw[0:3])  # the sensors on each side; more light, turn away
        return Float64MultiArray(data=[4.0 + 0.01 * (right - left), 4.0 + 0.01 * (left - right)])

    runs = []
    for _ in range(2):
        sim = start_lockstep_sim(launch, test_node, world, noise=True, seed=3)
        clients = LockstepClients(test_node, ['a', 'b', 'c'], {n: (Float64MultiArray, 'wheel_cmd') for n in 'abc'},
                                  braitenberg)
        run(test_node, clients, 150)
        runs.append({name: [pose(m) for m in clients.truth[name][:150]] for name in 'abc'})
        runs[-1]['raw'] = [clients.raw[name][:150] for name in 'abc']
        sim.stop()
        for name in list(clients.publishers):
            test_node.node.destroy_publisher(clients.publishers.pop(name))
    # The poses decide: each robot's commands come from its own readings, so equal paths mean equal readings were
    # answered. The raw lists are not compared: whether a client also received the step published before the
    # resume depends on DDS matching, which shifts the list by one without changing the run.
    assert {name: runs[0][name] for name in 'abc'} == {name: runs[1][name] for name in 'abc'}
    travelled = [sum(math.dist(p[:2], q[:2]) for p, q in zip(path, path[1:])) for path in map(runs[0].get, 'abc')]
    assert min(travelled) > 0.05  # they did drive
    assert max(max(raw) for robot in runs[0]['raw'] for raw in robot) > 300  # and saw something close


def test_ir_raw_is_the_lookup_table_at_a_known_distance(launch, test_node, tmp_path):
    """epuck1 faces the +x wall with ps0 0.02 m from it along the body's axis; noise off gives the table value."""
    gap = 0.02
    x = 0.5 - PS0[0] - gap
    world = write_world(tmp_path, [('epuck0', -0.2, 0.0, 0.0), ('epuck1', x, 0.0, 0.0)])
    launch('sim', *ros_args({'world': world, 'noise': False, 'real_time_factor': 0}))
    test_node.wait_for_simulator()
    raw = test_node.collect(Float64MultiArray, '/epuck1/ir_raw', 10)
    test_node.spin_until(lambda: raw, what='epuck1/ir_raw')
    distance = gap / math.cos(PS0[2])  # along the ps0 ray, from the sensor to the wall
    expected = np.interp(distance, *zip(*IR_TABLE))
    assert len(raw[-1].data) == 8
    assert raw[-1].data[0] == pytest.approx(expected, rel=1e-9)
    assert raw[-1].data[7] == pytest.approx(np.interp(gap / math.cos(0.2992), *zip(*IR_TABLE)), rel=1e-9)


def test_robots_parameter_places_robots_and_the_step_service_steps_once(launch, test_node):
    launch('sim', *ros_args({'robots': 5, 'seed': 7, 'paused': True, 'noise': False}))
    test_node.wait_for_simulator()
    worlds = test_node.collect(String, '/world', LATCHED)
    clocks, clock_sub = subscribe(test_node, Clock, '/clock')
    truth, truth_subs = {}, []
    for i in range(5):
        truth[i], subscription = subscribe(test_node, Odometry, f'/epuck{i}/ground_truth')
        truth_subs.append(subscription)
    test_node.spin_until(lambda: worlds, what='the world')
    robots = yaml.safe_load(worlds[0].data)['robots']
    assert [r['name'] for r in robots] == [f'epuck{i}' for i in range(5)]
    starts = np.array([r['start'] for r in robots])
    assert np.all(np.abs(starts[:, :2]) <= 0.5 - BODY_RADIUS)
    gaps = [math.dist(a, b) for i, a in enumerate(starts[:, :2]) for b in starts[i + 1:, :2]]
    assert min(gaps) >= 2 * BODY_RADIUS

    client = test_node.node.create_client(Trigger, '/step')
    assert client.wait_for_service(timeout_sec=20.0)
    test_node.spin_until(lambda: all(sub.get_publisher_count() for sub in [clock_sub, *truth_subs]),
                         what='the sim topics to match')
    for step in range(1, 4):
        future = client.call_async(Trigger.Request())
        test_node.spin_until(future.done, what='the step service')
        assert future.result().success
        test_node.spin_until(lambda: len(clocks) >= step and all(len(t) >= step for t in truth.values()),
                             what=f'step {step}')
    test_node.spin_for(0.3)
    assert [seconds(c.clock) for c in clocks] == pytest.approx([STEP, 2 * STEP, 3 * STEP], abs=1e-9)
    for i in range(5):
        assert len(truth[i]) == 3
        assert pose(truth[i][-1]) == pytest.approx(tuple(starts[i]), abs=1e-9)

    set_parameter(test_node, 'paused', boolean(False))
    future = client.call_async(Trigger.Request())
    test_node.spin_until(future.done, what='the step service while running')
    assert not future.result().success and 'not paused' in future.result().message


def test_real_time_factor_changes_take_effect_at_once_whatever_the_value(launch, test_node):
    sim = launch('sim', *ros_args({'real_time_factor': 1.0}))
    test_node.wait_for_simulator()
    clocks = test_node.collect(Clock, '/clock', EVERY_STEP)
    test_node.spin_until(lambda: len(clocks) > 2, what='the clock')
    factor = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=1e-6)
    set_parameter(test_node, 'real_time_factor', factor)  # the next step is 9 hours of wall time away
    factor.double_value = 1e-300  # one step: 1e290 years; must not overflow
    set_parameter(test_node, 'real_time_factor', factor)
    frozen = len(clocks)
    set_parameter(test_node, 'real_time_factor', ParameterValue(type=ParameterType.PARAMETER_INTEGER,
                                                                integer_value=20))  # an integer is a float too
    test_node.spin_until(lambda: len(clocks) > frozen + 10, timeout=30, what='the clock to resume at 20x')
    assert sim.proc.poll() is None and 'Overflow' not in sim.output()


@pytest.mark.parametrize('robots, steps, with_ranges', [(10, 600, True), (1, 3600, False)])
def test_a_slow_reliable_reader_gets_every_step_at_full_speed(launch, test_node, robots, steps, with_ranges):
    """A KEEP_ALL reader (as the recorder) slower than the sim at real_time_factor 0: the sim waits, nothing is lost
    though the run is longer than its publishers' history (`ack_window.history_steps`: 300 steps each with ten
    robots, 3,000 for a lone robot, whose run reads odom alone to stay short)."""
    assert history_steps(robots) < steps
    launch('sim', *ros_args({'real_time_factor': 0, 'paused': True, 'pause_at': steps * STEP,
                             'robots': robots}))
    test_node.wait_for_simulator()
    prefix = 'epuck3/' if robots > 1 else ''
    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1, reliability=ReliabilityPolicy.RELIABLE)
    odom, ranges = [], []

    def slow(received: list) -> Callable[[object], None]:
        def take(msg: object) -> None:
            received.append(msg)
            time.sleep(0.0005)  # a reader slower than the sim
        return take

    subscriptions = [test_node.node.create_subscription(Odometry, f'{prefix}odom', slow(odom), keep_all)]
    if with_ranges:
        subscriptions.append(test_node.node.create_subscription(Range, f'{prefix}proximity', slow(ranges), keep_all))
    test_node.spin_until(lambda: all(s.get_publisher_count() for s in subscriptions), what='the sim topics')
    set_parameter(test_node, 'paused', boolean(False))
    test_node.spin_until(lambda: len(odom) >= steps and len(ranges) >= 8 * steps * with_ranges, timeout=180,
                         what=f'{steps} steps of odom' + (' and proximity' if with_ranges else ''))
    assert [seconds(m.header.stamp) for m in odom] == pytest.approx([STEP * (k + 1) for k in range(steps)])
    if with_ranges:
        per_stamp = Counter(round(seconds(m.header.stamp) / STEP) for m in ranges)
        assert per_stamp == {k: 8 for k in range(1, steps + 1)}


SIGNAL_WHILE_STARTING = """
import sys
from epuck_ros.nodes import sim_node
asked = []
def shutdown_requested():   # the signal arrives while the third robot's ports are being made
    asked.append(True)
    return len(asked) > 3
sim_node.shutdown_requested = shutdown_requested
sim_node.main(sys.argv)
"""


def test_a_swarm_simulator_stops_while_starting(launch, tmp_path):
    """1,000 robots: SIGTERM while the ports were being made waited for all of them (about 15 s). It now stops
    between two robots' ports. The signal is made to arrive at a known point of the start (a real SIGTERM raced the
    start: once the whole start was over before the signal, in a loaded CI run)."""
    world = tmp_path / 'big.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    sim = launch('python', '-c', SIGNAL_WHILE_STARTING, *ros_args({'world': str(world), 'robots': 60, 'paused': True}))
    assert sim.proc.wait(timeout=60) == 0, sim.output()
    assert 'sim: stopped while starting' in sim.output() and 'sim ready' not in sim.output()


def test_a_swarm_simulator_stops_at_once_when_running(launch, test_node, tmp_path):
    """Once running, the node's 11,000 entities (1,000 robots) took 14 s to destroy one by one; beyond DESTROY_UP_TO
    robots it now ends without the one-by-one destruction, and exits 0."""
    import signal
    world = tmp_path / 'big.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    running = launch('sim', *ros_args({'world': str(world), 'robots': DESTROY_UP_TO + 10, 'paused': True}))
    test_node.wait_for_simulator(timeout=120)
    running.proc.send_signal(signal.SIGTERM)
    assert running.proc.wait(timeout=60) == 0, running.output()


def test_a_swarm_offers_a_sense_topic_once_it_has_a_subscriber(launch, test_node, tmp_path):
    """From SENSE_TOPICS_ON_DEMAND_FROM robots the sense topics' publishers are made on demand: none at start, the
    topic's once a subscriber to it is in the graph; the sense is then computed and published each step, and every
    other robot's stays without a publisher."""
    world = tmp_path / 'big.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    robots = SENSE_TOPICS_ON_DEMAND_FROM
    launch('sim', *ros_args({'world': str(world), 'robots': robots, 'paused': True, 'noise': False}))
    test_node.wait_for_simulator(timeout=120)
    node = test_node.node
    assert all(node.count_publishers(f'/epuck7/{topic}') == 0
               for topic in ('imu', 'camera/image_raw', 'camera/camera_info', 'ground_raw', 'light_raw'))
    imus, imu_sub = subscribe(test_node, Imu, '/epuck7/imu')
    infos, info_sub = subscribe(test_node, CameraInfo, '/epuck7/camera/camera_info')
    test_node.spin_until(lambda: imu_sub.get_publisher_count() and info_sub.get_publisher_count(), timeout=30,
                         what='the sim to offer the topics subscribed to')
    client = node.create_client(Trigger, '/step')
    assert client.wait_for_service(timeout_sec=20.0)
    future = client.call_async(Trigger.Request())
    test_node.spin_until(future.done, what='the step service')
    assert future.result().success
    test_node.spin_until(lambda: imus and infos, what='the step\'s imu and camera_info')
    assert seconds(imus[0].header.stamp) == pytest.approx(STEP) and imus[0].header.frame_id == 'epuck7/imu'
    assert imus[0].linear_acceleration.z == pytest.approx(9.81)
    assert infos[0].header.frame_id == 'epuck7/camera'
    assert node.count_publishers('/epuck8/imu') == 0 and node.count_publishers('/epuck7/ground_raw') == 0


def test_on_demand_makes_a_topic_once_its_reader_or_writer_is_in_the_graph():
    """`OnDemand`, without DDS: a publisher's topic is made once it has a reader, a subscription's once it has a
    writer; only the graph's topics are looked at, and a topic is made once."""
    made: list[str] = []
    demand = OnDemand()
    demand.add('/a/odom', lambda: made.append('odom'))
    demand.add('/a/wheel_cmd', lambda: made.append('wheel_cmd'), by_writer=True)
    demand.add('/b/odom', lambda: made.append('b'))
    readers, writers = {'/a/odom': 1, '/a/wheel_cmd': 1}, {'/a/odom': 0, '/a/wheel_cmd': 0}
    graph = ['/clock', '/a/odom', '/a/wheel_cmd']   # /b/odom: not in the graph, not asked about
    for make in demand.due(graph, readers.__getitem__, writers.__getitem__):
        make()
    assert made == ['odom'] and len(demand) == 2   # wheel_cmd has a reader (a recorder), no writer yet
    writers['/a/wheel_cmd'] = 1
    for make in demand.due(graph, readers.__getitem__, writers.__getitem__):
        make()
    assert made == ['odom', 'wheel_cmd'] and len(demand) == 1
    assert demand.due(graph, readers.__getitem__, writers.__getitem__) == []


def test_a_swarm_makes_a_robots_topics_once_someone_reads_or_drives_them(launch, test_node, tmp_path):
    """From TOPICS_ON_DEMAND_FROM robots no robot has its own topics at start; a controller that reads a robot's
    ir_raw and ground_truth and drives it by wheel_cmd (another by a stamped cmd_vel) gets them, in lockstep, step by
    step, and the latched collisions and robot_description arrive; every other robot stays without topics."""
    world = tmp_path / 'big.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    start_lockstep_sim(launch, test_node, str(world), robots=TOPICS_ON_DEMAND_FROM)
    node = test_node.node
    made = (('odom', 'ground_truth', 'ir_raw', 'proximity', 'joint_states', 'collisions', 'robot_description'),
            ('wheel_cmd', 'cmd_vel'))
    for name in ('epuck7', 'epuck9'):
        assert not any(node.count_publishers(f'/{name}/{topic}') for topic in made[0])
        assert not any(node.count_subscribers(f'/{name}/{topic}') for topic in made[1])

    def command(name: str, step: int, raw: list[float]) -> object:
        return Float64MultiArray(data=[HALF_SPEED, HALF_SPEED]) if name == 'epuck7' else Twist(angular=Vector3(z=1.0))

    clients = LockstepClients(test_node, ['epuck7', 'epuck9'], {'epuck7': (Float64MultiArray, 'wheel_cmd'),
                                                                'epuck9': (Twist, 'cmd_vel')}, command)
    collisions = test_node.collect(UInt32, '/epuck7/collisions', LATCHED)
    descriptions = test_node.collect(String, '/epuck7/robot_description', LATCHED)
    run(test_node, clients, 20)
    test_node.spin_until(lambda: collisions and descriptions, what='the latched collisions and robot_description')
    assert collisions[0].data == 0 and 'epuck7/base_link' in descriptions[0].data
    truth = clients.truth['epuck7'][:20]
    assert [seconds(m.header.stamp) for m in truth] == pytest.approx([STEP * (k + 1) for k in range(20)])
    steps = np.hypot(*np.diff([pose(m)[:2] for m in truth], axis=0).T)
    assert steps == pytest.approx(HALF_SPEED * WHEEL_RADIUS * STEP, abs=1e-9)
    assert clients.truth['epuck9'][19].twist.twist.angular.z == pytest.approx(1.0)
    assert not any(node.count_publishers(f'/epuck8/{topic}') for topic in made[0])
    assert not any(node.count_subscribers(f'/epuck8/{topic}') for topic in made[1])


def test_a_swarm_controller_reads_each_robots_ranges_as_that_robots_own_node_does():
    """The swarm controller turns every robot's raw IR values into ranges in one NumPy pass
    (`ranges_from_raw_rows`): the floats, to the bit, of `ranges_from_raw` robot by robot (a per-robot node's and a
    headless trial's), around the threshold of nothing seen, at each table row, between rows and beyond both ends."""
    from epuck_ros.behaviours.base import ranges_from_raw, ranges_from_raw_rows
    table_raws = [raw for _, raw in IR_TABLE]
    special = table_raws + [math.nextafter(raw, math.inf) for raw in table_raws] + \
        [math.nextafter(raw, -math.inf) for raw in table_raws] + [0.0, 77.0, 77.2, 80.0, 5000.0, math.nan]
    rng = np.random.default_rng(4)
    raws = np.concatenate([np.array(special + [67.19] * (-len(special) % 8)),
                           rng.uniform(0.0, 4500.0, 8 * 500), rng.uniform(60.0, 130.0, 8 * 500)]).reshape(-1, 8)
    rows = ranges_from_raw_rows(raws)
    assert len(rows) == len(raws)
    for row, raw in zip(rows, raws.tolist()):
        expected = ranges_from_raw(raw)
        assert np.array_equal(row, expected) and all(isinstance(value, float) for value in row)
        assert [math.copysign(1.0, value) for value in row] == [math.copysign(1.0, value) for value in expected]


def test_a_swarm_answer_sent_again_is_a_repeat_and_a_different_one_a_conflict(launch, test_node, tmp_path):
    """A swarm controller answers a step sent again with its answer again, byte for byte (`SwarmController`): the
    simulator drops it as a repeat, as a robot's own repeated wheel_cmd; a second answer that differs is a conflict,
    said with both commands. Before, the second copy went robot by robot and was compared with no command (the swarm's
    one NumPy pass noted none): a conflict, and the simulator died in its report (TypeError) - what a big swarm's
    first step, sent again after RESEND_AFTER while its answer was on its way, would have met."""
    from diagnostic_msgs.msg import DiagnosticStatus

    from epuck_ros.integrity import STATUS_TOPIC, WARN
    from epuck_ros.ros.ack_window import command_qos
    from epuck_ros.swarm_messages import COMMAND_FIELDS, COMMAND_TOPIC, OBSERVATION_TOPIC, SwarmLayout, SwarmReader
    names = ['epuck0', 'epuck1', 'epuck2']
    world = write_world(tmp_path, [(name, -0.3 + 0.3 * i, 0.0, 0.0) for i, name in enumerate(names)])
    sim = start_lockstep_sim(launch, test_node, world)
    commands = test_node.node.create_publisher(Float64MultiArray, COMMAND_TOPIC, command_qos(len(names)))
    layout, reader, answered = SwarmLayout(names, COMMAND_FIELDS), SwarmReader(), []

    def on_observation(data: bytes) -> None:
        read = reader.read(data)
        if read.stamp in answered:
            return
        answered.append(read.stamp)
        speeds = np.full((len(names), 2), 1.0 + len(answered) % 3)
        commands.publish(layout.to_bytes(speeds, read.stamp))
        speeds[1, 0] += len(answered) == 20   # the 20th step's second answer differs for epuck1
        commands.publish(layout.to_bytes(speeds, read.stamp))   # else the same again, as to a step sent again

    observations = test_node.node.create_subscription(Float64MultiArray, OBSERVATION_TOPIC, on_observation,
                                                      EVERY_STEP, raw=True)
    statuses, _ = subscribe(test_node, DiagnosticStatus, STATUS_TOPIC, LATCHED)
    commands.publish(SwarmLayout(names, ()).to_bytes(np.zeros((len(names), 0)), None))   # the declaration
    test_node.spin_until(lambda: commands.get_subscription_count() and observations.get_publisher_count(),
                         what='the swarm topics to match')
    set_parameter(test_node, 'lockstep_controllers',
                  ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=len(names)))
    set_parameter(test_node, 'paused', boolean(False))
    test_node.spin_until(lambda: len(answered) >= 30, timeout=60, what='30 steps answered')
    assert sim.proc.poll() is None, sim.output()[-3000:]
    test_node.spin_until(lambda: statuses and statuses[-1].level == bytes([WARN]), what='the conflict')
    # the first reason stays: no conflict before the 20th step, t = 0.640 s
    assert 'epuck1 got two different answers to t=0.640 s ([3.0, 3.0] on /swarm/command, then [4.0, 3.0] on ' \
           '/swarm/command)' in statuses[-1].message, statuses[-1].message
