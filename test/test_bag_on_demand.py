"""What a recording holds: the senses a controller or the user asked for, and every sample of every topic.

Real processes over DDS (`bringup`, `sim`, `record`), bags read back with rosbags (an independent reader)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from conftest import ros_args, set_sim_parameter
from rclpy.duration import Duration
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, Int32MultiArray, MultiArrayDimension, MultiArrayLayout, String
from std_srvs.srv import Trigger

from epuck_ros.ros.ack_window import command_qos
from epuck_ros.ros.qos import CLOCK_KEPT, LED_QOS, SENSES_ON_QOS

REPO = Path(__file__).resolve().parents[1]
LEDS_EVERY_STEP = REPO / 'test' / 'data' / 'webots' / 'leds_every_step.py'
AVOID_OBSTACLES = REPO / 'epuck_ros' / 'webots' / 'examples' / 'avoid_obstacles.py'
SENSE_TOPICS = ('/camera/image_raw', '/camera/camera_info', '/ground_raw', '/light_raw', '/imu')
STEP_NS = 32_000_000


def messages(bag: Path) -> dict[str, list]:
    """Every message of the bag, decoded by rosbags: topic -> messages in log-time order."""
    found: dict[str, list] = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection in reader.connections:
            found.setdefault(connection.topic, [])
        for connection, _, data in reader.messages():
            found[connection.topic].append(reader.deserialize(data, connection.msgtype))
    return found


LOST = re.compile(r'\]: lost')
"""How the recorder says it lost something (DDS message-lost events, gaps in the stamps)."""


def test_a_burst_of_led_messages_is_recorded_whole(launch, test_node, tmp_path):
    """The Webots shim's /leds publisher (link.LED_QOS) publishing far faster than a recorder acknowledges (as a
    script does at real_time_factor 0 while the recorder is busy): every message is in the bag, none reported lost.
    A reliable writer keeping one sample replaced the samples not yet sent or acknowledged."""
    recorder = launch('record', '-o', str(tmp_path / 'bag'), '/leds', *ros_args({}))
    recorder.wait_for_output('Recording to')
    leds = test_node.node.create_publisher(Int32MultiArray, 'leds', LED_QOS)
    test_node.spin_until(lambda: leds.get_subscription_count() >= 1, what='the recorder')
    count = 2000
    for index in range(count):
        leds.publish(Int32MultiArray(data=[index] + [0] * 9))
    assert leds.wait_for_all_acked(Duration(seconds=30))
    assert recorder.stop() == 0
    output = recorder.log_path.read_text()
    assert not LOST.search(output), output
    assert [int(msg.data[0]) for msg in messages(tmp_path / 'bag')['/leds']] == list(range(count))


def test_a_recorder_matched_after_a_controllers_first_answers_records_them(launch, test_node, tmp_path):
    """A controller's wheel_cmd (`command_qos`, as `avoid` and the Webots shim publish it) keeps its answers for a
    recorder that DDS matched with it only later: a loaded `bringup --record` bag lacked one robot's first 88 commands,
    its recorder's reader matched by the controller's writer after them. Here the answers go out before any recorder
    exists: the bag still has every one, in order."""
    commands = test_node.node.create_publisher(Float64MultiArray, 'wheel_cmd', command_qos(1))
    count = 100
    for step in range(1, count + 1):
        label = f'stamp={step * STEP_NS // 10**9}.{step * STEP_NS % 10**9:09d}'
        layout = MultiArrayLayout(dim=[MultiArrayDimension(label=label, size=2, stride=2)])
        commands.publish(Float64MultiArray(layout=layout, data=[float(step), -float(step)]))
    recorder = launch('record', '-o', str(tmp_path / 'bag'), '/wheel_cmd', *ros_args({}))
    test_node.spin_until(lambda: commands.get_subscription_count() >= 1, what='the recorder')
    assert commands.wait_for_all_acked(Duration(seconds=30))
    assert recorder.stop() == 0
    assert not LOST.search(recorder.log_path.read_text())
    assert [msg.data[0] for msg in messages(tmp_path / 'bag')['/wheel_cmd']] == [float(s) for s in range(1, count + 1)]


def test_leds_set_every_step_lose_no_sample_at_full_speed(launch, tmp_path):
    """A script that sets its LEDs every step, at real_time_factor 0: the bag has every LED message, in order, and
    the recorder reports no message lost (the latched /leds of depth 1 lost 9 samples in a 30 s run: a reliable
    writer keeping one sample overwrites it before a busy recorder has acknowledged it)."""
    bag = tmp_path / 'leds'
    run = launch('bringup', '--controller', str(LEDS_EVERY_STEP), '--duration', '20', '--real-time-factor', '0',
                 '--record', str(bag))
    assert run.proc.wait(timeout=240) == 0, run.output()
    assert not LOST.search(run.output()), run.output()
    leds = messages(bag)['/leds']
    counted = [int(msg.data[0]) for msg in leds]
    steps = round(20.0 / 0.032)
    # led0 = n goes out with the answer to step n + 1; the answer to the last step (n = steps - 1) drives nothing and
    # may come after the recorder stopped
    assert counted == list(range(1, len(counted) + 1)) and len(counted) >= steps - 2, counted[:5] + counted[-5:]
    assert all([int(bit) for bit in msg.data[1:]] == [count >> i & 1 for i in range(9)]
               for msg, count in zip(leds, counted))
    topics = messages(bag)
    assert len(topics['/ground_raw']) > 0   # the script reads its ground sensors: recorded
    assert not set(topics) & {'/camera/image_raw', '/camera/camera_info', '/light_raw', '/imu'}, sorted(topics)


def test_an_ir_only_run_is_recorded_without_the_senses_it_did_not_read(launch, tmp_path):
    """A script on the IR sensors alone, recorded: no camera, ground, light or IMU topic in the bag (the recorder
    subscribed to them, as to every topic, but does not ask for them: the simulator rendered none), every step
    topic whole."""
    bag = tmp_path / 'ir_only'
    run = launch('bringup', '--controller', str(AVOID_OBSTACLES), '--duration', '5', '--real-time-factor', '0',
                 '--record', str(bag))
    assert run.proc.wait(timeout=240) == 0, run.output()
    assert 'recorded while something asks for it' in run.output()   # subscribed, without asking
    topics = messages(bag)
    assert not set(topics) & set(SENSE_TOPICS), sorted(topics)
    steps = round(5.024 / 0.032)
    assert all(len(topics[topic]) == steps for topic in ('/clock', '/ground_truth', '/ir_raw', '/tf')), \
        {topic: len(found) for topic, found in topics.items()}


def test_record_senses_asks_for_a_sense_and_a_recorder_records_what_is_published(launch, test_node, tmp_path):
    """`record --senses camera` makes the simulator render the camera and records it; a second recorder that asks for
    nothing records the same images (what is published), and neither bag has a sense nobody asked for."""
    steps = 60
    sim = launch('sim', *ros_args({'real_time_factor': 0.0, 'paused': True, 'pause_at': steps * 0.032}))
    test_node.wait_for_simulator()
    asking = launch('record', '-o', str(tmp_path / 'asking'), '--senses', 'camera', *ros_args({'use_sim_time': True}))
    passive = launch('record', '-o', str(tmp_path / 'passive'), *ros_args({'use_sim_time': True}))
    for recorder in (asking, passive):
        recorder.wait_for_output('subscribed to /camera/image_raw')
    asking.wait_for_output('asking for it')
    # Kept ticks (transient local): the 60 steps may all be out before this reader matches (a CI run waited 60 s)
    clocks = test_node.collect(Clock, '/clock', CLOCK_KEPT)
    # The simulator renders the camera once its graph shows the asking reader's node by name (a reader it cannot
    # name yet does not ask); at full speed the 60 steps were once all out before that (no image in a loaded suite
    # run). So: one step at a time until it says the camera is on (`senses_on`), then the rest at full speed.
    senses_on = test_node.collect(String, 'senses_on', SENSES_ON_QOS)
    step = test_node.node.create_client(Trigger, 'step')
    assert step.wait_for_service(timeout_sec=20.0)
    for _ in range(steps // 2):
        if any('camera/image_raw' in msg.data for msg in senses_on):
            break
        done = step.call_async(Trigger.Request())
        test_node.spin_until(done.done, what='the step service')
        test_node.spin_for(0.1)
    assert any('camera/image_raw' in msg.data for msg in senses_on), [msg.data for msg in senses_on]
    set_sim_parameter(test_node, sim, 'paused', False)
    test_node.spin_until(lambda: clocks and clocks[-1].clock.sec * 10**9 + clocks[-1].clock.nanosec >= steps * STEP_NS,
                         timeout=60, what='the simulator at its pause_at')
    for recorder in (asking, passive):
        assert recorder.stop() == 0
    recorded = {name: messages(tmp_path / name) for name in ('asking', 'passive')}
    for name, topics in recorded.items():
        assert not set(topics) & {'/ground_raw', '/light_raw', '/imu'}, (name, sorted(topics))
        images = topics['/camera/image_raw']
        stamps = [msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec for msg in images]
        assert images and stamps[-1] == steps * STEP_NS and stamps == list(range(stamps[0], stamps[-1] + 1, STEP_NS))
        assert [msg.header.stamp for msg in topics['/camera/camera_info']][-len(images):] == \
            [msg.header.stamp for msg in images]
    asked, seen = recorded['asking']['/camera/image_raw'], recorded['passive']['/camera/image_raw']
    assert any(image.data.any() for image in asked)   # rendered: the arena's walls, not a black frame
    assert [bytes(image.data) for image in seen] == [bytes(image.data) for image in asked[-len(seen):]]


BURST_AND_EXIT = '''
import os, sys, time
import rclpy
from epuck_ros.ros.dds_profile import use_package_profile
from epuck_ros.webots.link import SimLink
use_package_profile()
rclpy.init()
link = SimLink('webots_controller', '', lambda: False)
deadline = time.monotonic() + 60
while link.node.count_subscribers('/leds') == 0 or link.node.count_publishers('/leds') == 0:
    link.publish_leds([0] * 10)   # the publisher is made with the first LEDs
    link._executor.spin_once(timeout_sec=0.05)
    if time.monotonic() > deadline:
        sys.exit('no reader of /leds')
time.sleep(1.0)   # the graph shows a reader before DDS has matched it
for count in range(1, int(sys.argv[1]) + 1):
    link.publish_leds([count] + [0] * 9)
link.close()
os._exit(0)   # as webots_controller ends (spinning.end_process)
'''


def test_a_controller_that_ends_leaves_the_recorder_everything_it_sent(launch, tmp_path):
    """A Webots controller's link publishing LEDs (and answers) faster than a recorder takes them, then ending as
    webots_controller ends (os._exit): the recorder has every message. Its writer's samples went with the process:
    a loaded bringup run lost its last 6 answers and LEDs (the controller stops first), a burst of 2,000 LEDs 1,250."""
    for burst in range(3):
        bag = tmp_path / f'bag{burst}'
        recorder = launch('record', '-o', str(bag), '/leds', *ros_args({}))
        recorder.wait_for_output('Recording to')
        sent = subprocess.run([sys.executable, '-c', BURST_AND_EXIT, '2000'], capture_output=True, text=True,
                              timeout=120)
        assert sent.returncode == 0, sent.stderr
        assert recorder.stop() == 0
        counted = {int(msg.data[0]) for msg in messages(bag)['/leds']}
        assert counted - {0} == set(range(1, 2001)), (burst, len(counted))
