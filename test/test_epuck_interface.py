"""The e-puck's own ROS 2 interface (epuck_ros/epuck_interface.py, ros/interface_ports.py) from the real `sim`
process over DDS: what `ros2 topic echo /ps1` gets, the scan against one built from /ps* and /tof as
webots_ros2_epuck's epuck_node.py builds it, the LEDs, the robots' namespaces, a swarm's topics made on demand, the
headless trial's bag, and the example nodes of epuck_ros/examples/epuck2 run as a user runs them."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Illuminance, Image, LaserScan, Range
from std_msgs.msg import Bool, Float64MultiArray, Int32, Int32MultiArray, UInt32
from std_srvs.srv import Trigger

from conftest import ALONE_ON_THE_DOMAIN, EVERY_MESSAGE, ros_args
from epuck_ros import epuck_interface as iface
from epuck_ros.conversions import stamp_from_label
from epuck_ros.ir_sensor import distance_from_raw
from epuck_ros.model import IR_LOOKUP_TABLE
from epuck_ros.ros.qos import LATCHED
from epuck_ros.ros.sense_ports import SENSE_TOPICS_ON_DEMAND_FROM

EXAMPLES = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'examples' / 'epuck2'
WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'
STEP = 0.032
ECHO_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
"""What `ros2 topic echo` subscribes with here (ros2cli's choose_qos): its default preset, sensor_data (depth 5),
with the reliability and durability every publisher of the topic offers (ours: reliable, volatile)."""


def seconds(stamp: object) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def near_wall_world(tmp_path: Path, robots: int = 1) -> Path:
    """A robot 0.05 m from a wall on its front left, so that ps7, ps6 and the ToF see something."""
    world = tmp_path / 'near_wall.yaml'
    starts = [{'name': f'epuck{i}', 'start': [0.0, 0.3 * i, 0.4]} for i in range(robots)]
    world.write_text(yaml.safe_dump({'arena': {'size': [1.0, 1.0]}, 'robots': starts,
                                     'boxes': [{'position': [0.12, 0.0], 'size': [0.05, 0.9]}]}))
    return world


# --- the pure part ------------------------------------------------------------------------------------------------

def epuck_node_scan(ir: list[float], tof: float) -> list[float]:
    """webots_ros2_epuck's epuck_node.py, its arithmetic as written there, on the Range messages' float32 values,
    stored in a LaserScan (float32)."""
    laser_dists = [0.0 if dist > 0.04 else dist for dist in ir]
    dist_tof = 0.0 if tof > 1.0 else tof
    msg = LaserScan()
    msg.ranges = [laser_dists[3] + 0.035, 0.0, 0.0, 0.0, laser_dists[2] + 0.035, 0.0, 0.0, laser_dists[1] + 0.035,
                  0.0, laser_dists[0] + 0.035, dist_tof + 0.035, laser_dists[7] + 0.035, 0.0,
                  laser_dists[6] + 0.035, 0.0, 0.0, laser_dists[5] + 0.035, 0.0, 0.0, 0.0, laser_dists[4] + 0.035]
    return msg.ranges.tolist()


def test_scan_ranges_are_epuck_nodes_to_the_bit() -> None:
    rng = np.random.default_rng(0)
    for _ in range(2000):
        ranges = rng.uniform(0.0, 0.08, 8).tolist()
        ranges[rng.integers(8)] = 0.04 + float(rng.choice([-1e-9, 0.0, 1e-9]))   # at the limit
        tof = float(rng.choice([rng.uniform(0.0, 2.0), 1.0, 0.9999999]))
        as_received = [float(np.float32(r)) for r in ranges]   # a Range's float32, as a reader gets it
        assert iface.scan_ranges(ranges, tof) == epuck_node_scan(as_received, float(np.float32(tof)))


def test_led_values_are_webots_led_values() -> None:
    assert [iface.led_value(0, True), iface.led_value(0, False), iface.led_value(1, 0x00FF00),
            iface.led_value(8, 1), iface.led_value(9, 0)] == [1, 0, 0x00FF00, 1, 0]
    assert sorted(iface.BOOL_LEDS) == [0, 2, 4, 6]


# --- over DDS -----------------------------------------------------------------------------------------------------

def step_once(test_node: object) -> None:
    client = test_node.node.create_client(Trigger, 'step')
    assert client.wait_for_service(timeout_sec=20.0)
    future = client.call_async(Trigger.Request())
    test_node.spin_until(future.done, what='the step service')
    assert future.result().success, future.result().message


def test_echo_ps1_prints_range_messages_of_each_step(launch: object, test_node: object, tmp_path: Path) -> None:
    """`ros2 topic echo /ps1` as the tutorial runs it: the topic and its type are in the graph before anyone reads
    it, and a reader with echo's QoS gets Range messages (frame ps1, INFRARED, the physical driver's fov and limits),
    each stamped with its step, whose range is the raw value of that step back through the table (as both sources
    publish it); ir_raw of the same steps says which."""
    launch('sim', *ros_args({'world': str(near_wall_world(tmp_path)), 'real_time_factor': 1.0}))
    test_node.wait_for_simulator()
    node = test_node.node
    test_node.spin_until(lambda: ('/ps1', ['sensor_msgs/msg/Range']) in node.get_topic_names_and_types(),
                         what='/ps1 in the graph')
    raws = test_node.collect(Float64MultiArray, 'ir_raw', EVERY_MESSAGE)
    echoed = test_node.collect(Range, '/ps1', ECHO_QOS)
    test_node.spin_until(lambda: len(echoed) > 20, what='ps1 messages')
    msg = echoed[-1]
    assert (msg.header.frame_id, msg.radiation_type) == ('ps1', Range.INFRARED)
    assert (msg.field_of_view, msg.min_range, msg.max_range) == \
        tuple(float(np.float32(v)) for v in (math.radians(15), 0.009, 0.025))
    by_stamp = {label_seconds(m): m.data.tolist() for m in raws}
    compared = 0
    for msg in echoed:
        t = seconds(msg.header.stamp)
        assert round(t / STEP) * STEP == pytest.approx(t, abs=1e-9)
        if t in by_stamp:
            assert msg.range == float(np.float32(distance_from_raw(by_stamp[t][1], IR_LOOKUP_TABLE)))
            compared += 1
    assert compared > 10


def test_scan_equals_one_built_from_ps_and_tof_as_epuck_node_builds_it(launch: object, test_node: object,
                                                                       tmp_path: Path) -> None:
    """Our `scan` against the example node scan_from_ranges.py (epuck_node.py's arithmetic on our /ps* and /tof,
    one scan per instant once its nine readings are in): the same ranges to the bit, step by step, with IR noise
    and a wall that ps6, ps7 and the ToF see; the rest of the message as epuck_node.py fills it; the TF frame."""
    launch('sim', *ros_args({'world': str(near_wall_world(tmp_path)), 'real_time_factor': 1.0}))
    test_node.wait_for_simulator()
    launch('python', str(EXAMPLES / 'scan_from_ranges.py'))
    ours = test_node.collect(LaserScan, 'scan', EVERY_MESSAGE)
    rebuilt = test_node.collect(LaserScan, 'scan_rebuilt', EVERY_MESSAGE)
    static = test_node.collect(_tf_message(), '/tf_static', LATCHED)
    test_node.spin_until(lambda: len(rebuilt) > 30 and len(ours) > 30 and static, timeout=60.0,
                         what='both scans')
    by_stamp = {seconds(m.header.stamp): m for m in ours}
    pairs = [(by_stamp[seconds(m.header.stamp)], m) for m in rebuilt if seconds(m.header.stamp) in by_stamp]
    assert len(pairs) > 20
    for mine, theirs in pairs:
        assert mine.ranges.tolist() == theirs.ranges.tolist()
        assert (mine.header.frame_id, mine.angle_min, mine.angle_max, mine.angle_increment, mine.range_min,
                mine.range_max) == (theirs.header.frame_id, theirs.angle_min, theirs.angle_max,
                                    theirs.angle_increment, theirs.range_min, theirs.range_max)
        assert mine.scan_time == pytest.approx(STEP)
    seen = np.array([m.ranges.tolist() for m, _ in pairs])
    assert (seen[:, 10] > 0.035).all() and (seen[:, 13] > 0.035).all()   # the ToF and ps6 see the wall
    assert len({tuple(row) for row in seen}) > 1                          # noise: the steps differ
    [laser] = [t for t in static[-1].transforms if t.child_frame_id == 'laser_scanner']
    assert laser.header.frame_id == 'base_link' and laser.transform.translation.z == pytest.approx(0.033)


def _tf_message() -> type:
    from tf2_msgs.msg import TFMessage
    return TFMessage


def test_leds_light_and_camera_topics_under_each_robots_name(launch: object, test_node: object,
                                                             tmp_path: Path) -> None:
    """With two robots every interface topic is under the robot's name, its frames prefixed; led0 (Bool), led1
    (Int32 0xRRGGBB) and led9 set that robot's `leds` as Webots' LED.set takes them; ls0..ls7 carry light_raw's
    values (the physical driver's raw value), image_raw the camera's rgb8, stamped with the step."""
    launch('sim', *ros_args({'world': str(near_wall_world(tmp_path, robots=2)), 'real_time_factor': 1.0}))
    test_node.wait_for_simulator()
    node = test_node.node
    leds = test_node.collect(Int32MultiArray, 'epuck1/leds', LATCHED)
    light = test_node.collect(Float64MultiArray, 'epuck1/light_raw', EVERY_MESSAGE)
    ls3 = test_node.collect(Illuminance, 'epuck1/ls3', EVERY_MESSAGE)
    images = test_node.collect(Image, 'epuck0/image_raw', EVERY_MESSAGE)
    infos = test_node.collect(CameraInfo, 'epuck0/camera_info', EVERY_MESSAGE)
    ranges = test_node.collect(Range, 'epuck1/ps7', EVERY_MESSAGE)
    publishers = [(node.create_publisher(Bool, 'epuck1/led0', 10), Bool(data=True)),
                  (node.create_publisher(Int32, 'epuck1/led1', 10), Int32(data=0x00FF00)),
                  (node.create_publisher(Int32, 'epuck1/led9', 10), Int32(data=1))]
    test_node.spin_until(lambda: all(pub.get_subscription_count() for pub, _ in publishers), what='the LEDs')
    for publisher, msg in publishers:
        publisher.publish(msg)
    test_node.spin_until(lambda: leds and leds[-1].data.tolist() == [1, 0x00FF00] + [0] * 7 + [1],
                         what='epuck1/leds')
    test_node.spin_until(lambda: len(ls3) > 5 and len(images) > 5 and infos and ranges, what='the sense topics')
    assert ranges[-1].header.frame_id == 'epuck1/ps7' and ls3[-1].header.frame_id == 'epuck1/ls3'
    assert images[-1].header.frame_id == 'epuck0/camera' and images[-1].encoding == 'rgb8'
    assert infos[-1].header.frame_id == 'epuck0/camera'
    for msg in (*images, *ls3, *ranges):   # each stamped with its step
        t = seconds(msg.header.stamp)
        assert round(t / STEP) * STEP == pytest.approx(t, abs=1e-9)
    raw = {label_seconds(m): m.data.tolist() for m in light}
    matched = [(msg.illuminance, raw[seconds(msg.header.stamp)][3]) for msg in ls3 if seconds(msg.header.stamp) in raw]
    assert matched and all(ours == theirs for ours, theirs in matched)
    assert node.count_publishers('/ps7') == 0   # no robot is unnamed


def label_seconds(msg: Float64MultiArray) -> float:
    """The step a raw array names (its layout's label), in seconds."""
    sec, nanosec = stamp_from_label(msg.layout.dim[0].label)
    return sec + 1e-9 * nanosec


# --- the example nodes, as a user runs them beside `sim` ----------------------------------------------------------

class ExampleRun:
    """`sim` (lockstep, real_time_factor 0, paused until the example's cmd_vel is in the graph, pausing at
    `duration`) and an example node of epuck_ros/examples/epuck2 run with python, as a user runs it. A Twist names no
    step: the simulator waits at most OWN_RATE_WAIT a step for it (it is at its own rate)."""

    def __init__(self, launch: object, test_node: object, example: str, duration: float, world: Path | None = None,
                 *args: str) -> None:
        self.test_node, self.duration = test_node, duration
        self.truth = test_node.collect(Odometry, 'ground_truth', EVERY_MESSAGE)
        self.collisions = test_node.collect(UInt32, 'collisions', LATCHED)
        params = {**ALONE_ON_THE_DOMAIN, 'real_time_factor': 0.0, 'lockstep': True, 'paused': True,
                  'pause_at': float(duration),
                  **({'world': str(world)} if world else {})}
        self.sim = launch('sim', *ros_args(params))
        test_node.wait_for_simulator()
        self.node = launch('python', str(EXAMPLES / f'{example}.py'), *args)
        test_node.spin_until(lambda: test_node.node.count_publishers('cmd_vel') > 0
                             or self.node.proc.poll() is not None, what=f'{example}\'s cmd_vel')
        client = AsyncParameterClient(test_node.node, 'sim')
        assert client.wait_for_services(20.0)
        future = client.set_parameters([Parameter('lockstep_controllers', value=1), Parameter('paused', value=False)])
        test_node.spin_until(future.done, what='sim to resume')

    def finish(self) -> np.ndarray:
        """Spin until the sim paused at `duration`; the ground truth as rows (x, y)."""
        self.test_node.spin_until(lambda: self.truth and seconds(self.truth[-1].header.stamp) >= self.duration - 1e-6,
                                  timeout=60.0 + 3.0 * self.duration, what=f'{self.duration} simulated s')
        return np.array([(m.pose.pose.position.x, m.pose.pose.position.y) for m in self.truth])


def test_odometry_drive_example_stops_after_its_distance(launch: object, test_node: object) -> None:
    """odometry_drive.py (an odometry loop on `odom` with a Twist on `cmd_vel`, as drive_calibrator.py) drives 0.2 m
    by odometry, stops and exits 0; the ground truth says it went that far."""
    run = ExampleRun(launch, test_node, 'odometry_drive', 10.0, None, '--ros-args', '-p', 'distance:=0.2')
    assert run.node.proc.wait(timeout=120) == 0, run.node.output()
    path = run.finish()
    travelled = float(np.hypot(*(path[-1] - path[0])))
    print(f'odometry_drive: {travelled:.4f} m by ground truth')
    # A Twist is at its own rate: the stop comes a step or a few late (under load the simulator waits 10 ms a step
    # for it), and cmd_timeout (0.5 s, 0.025 m at its speed) bounds that whatever the load.
    assert 0.2 - 0.002 <= travelled <= 0.2 + 0.025 + 0.002
    assert (path[-1] == path[-2]).all()   # it stands
    assert 'stopping' in run.node.output()


def test_random_walker_example_avoids_the_walls_for_a_minute(launch: object, test_node: object,
                                                             tmp_path: Path) -> None:
    """random_walker.py reads `tof`, `ps0` and `ps7` (Range) and drives with a Twist: in a walled 1 m arena, 60
    simulated seconds without a contact, going places. A Twist is at its own rate, so the walker may answer some
    steps late under load: on the core, with its commands 10 steps late, 0 of 20 seeds touched a wall. (Three front
    rays miss a box's corner that passes between them at the body's edge: 6 of 20 seeds touched a box of the default
    arena, so the arena here has walls only.)"""
    world = tmp_path / 'walls.yaml'
    world.write_text('arena: {size: [1.0, 1.0]}\n')
    run = ExampleRun(launch, test_node, 'random_walker', 60.0, world, '--ros-args', '-p', 'seed:=3')
    path = run.finish()
    travelled = float(np.hypot(*np.diff(path, axis=0).T).sum())
    contacts = max((m.data for m in run.collisions), default=0)
    print(f'random_walker: {travelled:.2f} m in 60 s, {contacts} contacts')
    assert contacts == 0 and travelled > 1.0


def test_a_swarms_interface_topics_are_made_once_read(launch: object, test_node: object,
                                                      tmp_path: Path) -> None:
    """From SENSE_TOPICS_ON_DEMAND_FROM robots no robot's topic is in the graph at start, its own or the interface's
    (a swarm's discovery costs what it did): a reader of epuck7/ps2 makes its publisher, a writer of epuck7/led8 its
    subscription; that robot then publishes its ps2 each step and its `leds` when told, and no other robot's topic
    exists."""
    world = tmp_path / 'big.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    launch('sim', *ros_args({'world': str(world), 'robots': SENSE_TOPICS_ON_DEMAND_FROM, 'paused': True}))
    test_node.wait_for_simulator(timeout=120)
    node = test_node.node
    names = {name for name, _ in node.get_topic_names_and_types()}
    assert '/clock' in names and not names & {f'/epuck{i}/{topic}' for i in range(SENSE_TOPICS_ON_DEMAND_FROM)
                                              for topic in ('odom', 'ps2', 'scan', 'ls0', 'image_raw', 'camera_info')}
    assert node.count_subscribers('/epuck7/led8') == 0
    ranges = test_node.collect(Range, '/epuck7/ps2', EVERY_MESSAGE)
    leds = test_node.collect(Int32MultiArray, '/epuck7/leds', LATCHED)
    led8 = node.create_publisher(Int32, '/epuck7/led8', 10)
    test_node.spin_until(lambda: node.count_publishers('/epuck7/ps2') and led8.get_subscription_count(),
                         timeout=30, what='the sim to make the topics read and written')
    step_once(test_node)
    test_node.spin_until(lambda: ranges, what='the step\'s ps2')
    assert seconds(ranges[0].header.stamp) == pytest.approx(STEP) and ranges[0].header.frame_id == 'epuck7/ps2'
    led8.publish(Int32(data=1))
    test_node.spin_until(lambda: leds, what='epuck7/leds')
    assert leds[-1].data.tolist() == [0] * 8 + [1, 0]
    assert node.count_publishers('/epuck8/ps2') == 0 and node.count_subscribers('/epuck8/led8') == 0


LIGHT_SCRIPT = """
from controller import Robot
robot = Robot()
sensors = [robot.getDevice(f'ls{i}') for i in range(8)]
for sensor in sensors:
    sensor.enable(32)
for name, speed in (('left wheel motor', 2.0), ('right wheel motor', 3.0)):
    robot.getDevice(name).setPosition(float('inf'))
    robot.getDevice(name).setVelocity(speed)
while robot.step(32) != -1:
    pass
"""


def test_a_headless_bag_has_the_interface_topics_a_recorder_gets_over_ros(tmp_path: Path) -> None:
    """A script that reads its light sensors, through `bringup --controller --record` and `webots_controller
    --headless --record`: both bags have ls0..ls7 (each Illuminance the step's light_raw value, frame lsN), equal
    topic by topic (test_bag_headless's comparison); the topics nobody read are in neither (the IR's, scan,
    image_raw: a recorder alone asks for nothing)."""
    from test_bag_headless import compare, read, run_both, step_of
    script = tmp_path / 'light.py'
    script.write_text(LIGHT_SCRIPT)
    options = ['--seed', '4', '--duration', '2', '--world', str(WORLDS / 'lit_arena.yaml')]
    ros = [read(bag) for bag in run_both(tmp_path, ['--controller', str(script), *options],
                                         ['webots_controller', str(script), '--headless', *options, '--record',
                                          str(tmp_path / 'headless')])]
    headless = read(tmp_path / 'headless')
    for bag in (*ros, headless):
        assert bag['/ls5']['type'] == 'sensor_msgs/msg/Illuminance'
        assert not {'/image_raw', '/scan', '/ps0', '/camera_info', '/leds'} & set(bag)
        light = {step_of(msg): msg.data.tolist() for msg in bag['/light_raw']['messages']}
        ls5 = bag['/ls5']['messages']
        assert len(ls5) > 50 and ls5[0].header.frame_id == 'ls5'
        assert all(light[(msg.header.stamp.sec, msg.header.stamp.nanosec)][5] == msg.illuminance for msg in ls5)
    for over_ros in ros:
        compare(over_ros, headless)


def test_the_readme_node_on_the_interface_answers_by_name_and_repeats_its_run(launch: object) -> None:
    """stamped_ranges_node.py, the README's node written on the e-puck's own topics (ps0..ps7 in, a TwistStamped on
    cmd_vel stamped with the step it read out), through `bringup --controller`: lockstep, reproducible, it turns
    away from what it meets (no contact in 30 s), and a second run ends at the same pose to the last printed digit."""
    summaries = []
    for _ in range(2):
        run = launch('bringup', '--controller', str(EXAMPLES / 'stamped_ranges_node.py'), '-p', 'cmd_vel_stamped:=true',
                     '--duration', '30', '--real-time-factor', '0', '--seed', '2')
        assert run.proc.wait(timeout=300) == 0, run.output()
        output = run.output()
        assert '[bringup] reproducible:' in output and 'Traceback' not in output, output
        summary = next(line for line in output.splitlines() if 'final pose' in line)
        assert ', 0 contacts' in summary and 'Straight line' not in output, output
        summaries.append(summary)
    assert summaries[0] == summaries[1]
