"""`foxglove` and `bringup --foxglove` seen from outside: the simulator and the bridge run as their own processes
over DDS, and a WebSocket client written here from the Foxglove protocol (websocket-client, the SDK's subprotocol)
subscribes to channels and decodes what it receives with mcap_ros2 from the schemas the server advertised.

The simulator is stepped with its `step` service while paused, so what the client must receive is a matter of
steps, never of timing: waits are for conditions (bounded only so that a failure ends).
"""
from __future__ import annotations

import json
import re
import socket
import struct
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import pytest
import websocket
from conftest import BIN_DIR, processes_in_this_domain, ros_args
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory

from epuck_ros.foxglove import layout

SUBPROTOCOL = 'foxglove.sdk.v1'
"""The subprotocol foxglove-sdk's server accepts (rust/foxglove/src/websocket/handshake.rs; the app offers it)."""
MESSAGE_DATA, TIME = 1, 2
"""Binary opcodes of the server's messages (Foxglove WebSocket protocol v1)."""
WAIT = 60.0
"""Wall seconds a condition may take on a loaded machine before the test fails."""
URDF_FILE = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'urdf' / 'epuck.urdf'
SCHEMA_REFERENCE = Path(__file__).parent / 'data' / 'schema_nav_msgs_Odometry.ros2msg.txt'
"""rosbag2's own text for nav_msgs/msg/Odometry (test_bag_format compares the bags' schemas with it)."""
BLOCK = re.compile(r'\n={80}\nMSG: (\S+)\n')
"""rosbag2's separator between the .msg texts of a schema and the types it uses."""


class FoxgloveClient:
    """The client side of the protocol, nothing of the package's: JSON control messages (serverInfo, advertise,
    unadvertise; subscribe, unsubscribe), binary messageData (opcode 1: subscription id, log time, payload) and
    time (opcode 2). Each payload is decoded with mcap_ros2 from its channel's advertised schema."""

    def __init__(self, port: int) -> None:
        self.ws = websocket.create_connection(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], timeout=0.2)
        self.server_info: dict = {}
        self.channels: dict[str, dict] = {}
        """Advertised channels by topic."""
        self.unadvertised: set[int] = set()
        self.received: dict[str, list[tuple[int, object]]] = defaultdict(list)
        """(log time, decoded message) by topic."""
        self.times: list[int] = []
        self._subscribed: dict[int, dict] = {}
        self._decoders: dict[int, Callable[[bytes], object]] = {}
        self._next_id = 1

    def pump(self, until: Callable[[], bool], what: str, between: Callable[[], None] | None = None) -> None:
        """Read messages until `until()`; `between` runs whenever nothing is waiting (a step of the simulator)."""
        deadline = time.monotonic() + WAIT
        while not until():
            if time.monotonic() > deadline:
                raise AssertionError(f'no {what} within {WAIT:.0f} s; channels: {sorted(self.channels)}')
            try:
                opcode, data = self.ws.recv_data()
            except websocket.WebSocketTimeoutException:
                if between is not None:
                    between()
                continue
            if opcode == websocket.ABNF.OPCODE_TEXT:
                self._control(json.loads(data))
            else:
                self._binary(data)

    def _control(self, message: dict) -> None:
        if message['op'] == 'serverInfo':
            self.server_info = message
        elif message['op'] == 'advertise':
            self.channels.update({channel['topic']: channel for channel in message['channels']})
        elif message['op'] == 'unadvertise':
            self.unadvertised.update(message['channelIds'])
            self.channels = {t: c for t, c in self.channels.items() if c['id'] not in self.unadvertised}

    def _binary(self, data: bytes) -> None:
        if data[0] == TIME:
            self.times.append(struct.unpack_from('<Q', data, 1)[0])
        elif data[0] == MESSAGE_DATA:
            subscription, log_time = struct.unpack_from('<IQ', data, 1)
            channel = self._subscribed[subscription]
            if channel['id'] not in self._decoders:
                schema = Schema(id=channel['id'], name=channel['schemaName'], encoding=channel['schemaEncoding'],
                                data=channel['schema'].encode())
                self._decoders[channel['id']] = DecoderFactory().decoder_for(channel['encoding'], schema)
            self.received[channel['topic']].append((log_time, self._decoders[channel['id']](bytes(data[13:]))))

    def subscribe(self, *topics: str) -> None:
        subscriptions = []
        for topic in topics:
            subscriptions.append({'id': self._next_id, 'channelId': self.channels[topic]['id']})
            self._subscribed[self._next_id] = self.channels[topic]
            self._next_id += 1
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

    def unsubscribe(self, *topics: str) -> None:
        ids = [sid for sid, channel in self._subscribed.items() if channel['topic'] in topics]
        self.ws.send(json.dumps({'op': 'unsubscribe', 'subscriptionIds': ids}))

    def last(self, topic: str) -> object:
        return self.received[topic][-1][1]

    def close(self) -> None:
        self.ws.close()


def start_bridge(launch, *args: str):
    """`foxglove --port 0` on the test run's domain, and the port it printed."""
    bridge = launch('foxglove', '--port', '0', *args)
    bridge.wait_for_output('foxglove: ws://', timeout=WAIT)
    return bridge, int(re.search(r'ws://127\.0\.0\.1:(\d+)', bridge.output()).group(1))


def rosbag2_layout(schema: str) -> list[str]:
    """The types after the root one, in rosbag2's order (the reference's comments are another release's)."""
    return BLOCK.split(schema)[1::2]


def installed_msg(name: str) -> str:
    package, message = name.split('/')
    return (Path(sys.prefix) / 'share' / package / 'msg' / f'{message}.msg').read_text()


def stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def readers_of(test_node, topic: str) -> list[str]:
    """The nodes the graph shows subscribed to `topic`."""
    return [info.node_name for info in test_node.node.get_subscriptions_info_by_topic(topic)]


def test_a_run_seen_through_foxglove(launch, test_node):
    """Topics appear as the simulator publishes them, in their ROS 2 encoding; the values decoded by an independent
    reader are what ROS delivered; /clock is the server's time; the camera is read only while a client shows it."""
    from nav_msgs.msg import Odometry
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64MultiArray
    from std_srvs.srv import Trigger
    bridge, port = start_bridge(launch)   # before the simulator: its topics join later
    client = FoxgloveClient(port)
    try:
        launch('sim', *ros_args({'paused': True, 'noise': False, 'cmd_timeout': 1000.0}))
        test_node.wait_for_simulator()
        wanted = set(layout.TOPICS.values()) | {'/clock', '/tf', '/tf_static', '/ir_raw'}
        client.pump(lambda: wanted <= set(client.channels), 'channel for every topic of the layout')
        assert client.server_info['capabilities'] == ['time']
        odom = client.channels['/odom']
        assert (odom['encoding'], odom['schemaEncoding']) == ('cdr', 'ros2msg')
        assert odom['schemaName'] == 'nav_msgs/msg/Odometry'
        assert rosbag2_layout(odom['schema']) == rosbag2_layout(SCHEMA_REFERENCE.read_text())
        for name, text in zip(['nav_msgs/Odometry', *rosbag2_layout(odom['schema'])], BLOCK.split(odom['schema'])[::2]):
            assert text == installed_msg(name), f'{name}: the installed .msg file, as rosbag2 embeds it'
        for topic in ('/odom', '/camera/image_raw', '/robot_description'):
            assert 'foxglove' not in readers_of(test_node, topic), f'{topic} read before a client asked'

        shown = ['/clock', '/odom', '/tf', '/tf_static', '/robot_description', '/camera/image_raw']
        client.subscribe(*shown)
        test_node.spin_until(lambda: all('foxglove' in readers_of(test_node, t) for t in shown if t != '/clock'),
                             timeout=WAIT, what='the bridge to subscribe to what the client shows')
        ros_odom = test_node.collect(Odometry, '/odom', QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        wheels = test_node.node.create_publisher(Float64MultiArray, '/wheel_cmd', 10)
        test_node.spin_until(lambda: wheels.get_subscription_count() > 0, what='the simulator to read wheel_cmd')
        wheels.publish(Float64MultiArray(data=[3.0, 3.0]))
        stepper = test_node.node.create_client(Trigger, '/step')

        def step() -> int:
            """One step; its time in nanoseconds (the service answers once the step is published)."""
            future = stepper.call_async(Trigger.Request())
            test_node.spin_until(future.done, timeout=WAIT, what='a step')
            assert future.result().success, future.result().message
            return round(float(future.result().message.removeprefix('t=').removesuffix(' s')) * 1000) * 10**6

        # Step until the bridge's readers are matched (the first messages of each reach the client), then ten more.
        client.pump(lambda: all(client.received[t] for t in shown), 'messages on every shown topic', between=step)
        last_ns = [step() for _ in range(10)][-1]
        client.pump(lambda: stamp_ns(client.last('/clock').clock) == last_ns
                    and stamp_ns(client.last('/odom').header.stamp) == last_ns and client.times[-1:] == [last_ns],
                    'the last step on /clock, /odom and the server time')
        test_node.spin_until(lambda: ros_odom and stamp_ns(ros_odom[-1].header.stamp) == last_ns, timeout=WAIT,
                             what='the last odometry over ROS')

        clock = [stamp_ns(message.clock) for _, message in client.received['/clock']]
        assert all(log_time == tick for (log_time, _), tick in zip(client.received['/clock'], clock))
        assert set(client.times) <= set(clock), 'every server time is a /clock tick'
        assert client.times == sorted(client.times)
        assert all(log_time in set(clock) | {0} for log_time, _ in client.received['/odom']), 'at the sim\'s time'
        # The same steps' odometry as ROS delivered it to this test (its reader may have matched a step later).
        by_stamp = {stamp_ns(message.header.stamp): message for message in ros_odom}
        both = [message for _, message in client.received['/odom'] if stamp_ns(message.header.stamp) in by_stamp]
        assert stamp_ns(both[-1].header.stamp) == last_ns
        for message in both:
            over_ros = by_stamp[stamp_ns(message.header.stamp)]
            assert (message.pose.pose.position.x, message.pose.pose.position.y, message.pose.pose.orientation.z,
                    message.twist.twist.linear.x, message.header.frame_id, message.child_frame_id) == (
                        over_ros.pose.pose.position.x, over_ros.pose.pose.position.y,
                        over_ros.pose.pose.orientation.z, over_ros.twist.twist.linear.x,
                        over_ros.header.frame_id, over_ros.child_frame_id)
        moved = client.last('/odom')
        assert moved.pose.pose.position.x > 0.01 and moved.twist.twist.linear.x == pytest.approx(3.0 * 0.02, rel=0.05)
        base = [t for _, m in client.received['/tf'] for t in m.transforms if t.child_frame_id == 'base_link'
                and stamp_ns(t.header.stamp) == last_ns]
        assert base and base[0].transform.translation.x == moved.pose.pose.position.x
        assert client.last('/robot_description').data == URDF_FILE.read_text()
        static = {(t.header.frame_id, t.child_frame_id) for _, m in client.received['/tf_static'] for t in m.transforms}
        assert {('world', 'odom'), ('base_link', 'camera')} <= static
        image = client.last('/camera/image_raw')
        assert (image.encoding, image.header.frame_id) == ('rgb8', 'camera')
        assert len(image.data) == image.height * image.step
        assert image.width * 3 == image.step and len(set(image.data)) > 1, 'a rendered picture'

        client.unsubscribe('/camera/image_raw')
        test_node.spin_until(lambda: 'foxglove' not in readers_of(test_node, '/camera/image_raw'), timeout=WAIT,
                             what='the bridge to stop reading the camera once no client shows it')
        assert 'foxglove' in readers_of(test_node, '/odom')
    finally:
        client.close()
    assert bridge.stop() == 0, bridge.log_path.read_text()
    assert 'Traceback' not in bridge.log_path.read_text()


def test_several_robots_two_clients_and_a_simulator_that_ends(launch, test_node):
    """Each robot's namespaced topics are channels; a latched topic reaches a client that subscribes after another;
    the channels go when the simulator does."""
    sim = launch('sim', *ros_args({'robots': 2}))
    test_node.wait_for_simulator()
    bridge, port = start_bridge(launch)
    first, second = FoxgloveClient(port), FoxgloveClient(port)
    try:
        robots = {f'/epuck{i}/{topic}' for i in (0, 1) for topic in ('odom', 'robot_description', 'camera/image_raw')}
        for client in (first, second):
            client.pump(lambda: robots <= set(client.channels), 'channels of both robots')
        description = '/epuck1/robot_description'
        assert first.channels[description]['schemaName'] == 'std_msgs/msg/String'
        first.subscribe(description)
        first.pump(lambda: first.received[description], 'the latched description')
        second.subscribe(description)
        second.pump(lambda: second.received[description], 'the latched description for a later client')
        for client in (first, second):
            assert '<link name="epuck1/base_link">' in client.last(description).data
        ids = {first.channels[topic]['id'] for topic in robots}
        sim.stop()
        first.pump(lambda: ids <= first.unadvertised, 'the channels withdrawn once the simulator has gone')
        assert not robots & set(first.channels)
    finally:
        first.close()
        second.close()
    assert bridge.stop() == 0, bridge.log_path.read_text()


def test_a_swarm_through_foxglove_makes_no_robot_topic(launch, test_node, tmp_path):
    """200 robots (from which the simulator makes a robot's topics only once someone reads them): the bridge
    advertises what the graph has and subscribes only what its client shows, so a client reading every robot's step
    from swarm/observation makes the simulator make none of the robots' own topics."""
    from std_srvs.srv import Trigger
    world = tmp_path / 'arena5.yaml'
    world.write_text('arena: {size: [5.0, 5.0]}\n')
    launch('sim', *ros_args({'paused': True, 'robots': 200, 'world': world}))
    test_node.wait_for_simulator()
    bridge, port = start_bridge(launch)
    client = FoxgloveClient(port)
    stepper = test_node.node.create_client(Trigger, '/step')
    try:
        client.pump(lambda: '/swarm/observation' in client.channels, 'the swarm observation channel')
        client.subscribe('/swarm/observation')
        client.pump(lambda: client.received['/swarm/observation'], 'a swarm observation',
                    between=lambda: stepper.call_async(Trigger.Request()))
        step = client.last('/swarm/observation')
        assert [dim.size for dim in step.layout.dim[-2:]] == [200, 20]   # every robot's step, in one message
        robot_topics = [name for name, _ in test_node.node.get_topic_names_and_types()
                        if re.match(r'/epuck\d+/', name)]
        assert robot_topics == []
        assert not any(re.match(r'/epuck\d+/', channel) for channel in client.channels)
    finally:
        client.close()
    assert bridge.stop() == 0, bridge.log_path.read_text()


def taken_port() -> socket.socket:
    """A socket listening on a free loopback port: that port is taken while it lives."""
    holder = socket.socket()
    holder.bind(('127.0.0.1', 0))
    holder.listen()
    return holder


def test_a_taken_port_is_refused_in_one_line():
    with taken_port() as holder:
        port = holder.getsockname()[1]
        runs = [subprocess.run([str(BIN_DIR / 'foxglove'), '--port', str(port)], capture_output=True, text=True,
                               timeout=WAIT),
                subprocess.run([str(BIN_DIR / 'bringup'), 'forward', '--foxglove', str(port)], capture_output=True,
                               text=True, timeout=WAIT)]
    for run in runs:
        assert run.returncode == 2, run.stdout + run.stderr
        lines = (run.stdout + run.stderr).strip().splitlines()
        assert len(lines) == 1 and f'cannot serve on 127.0.0.1:{port}: Address already in use' in lines[0], lines
    assert processes_in_this_domain() == []


def test_bringup_refuses_the_views_port_and_serves_foxglove_with_the_run():
    clash = subprocess.run([str(BIN_DIR / 'bringup'), 'forward', '--view', '--foxglove'], capture_output=True,
                           text=True, timeout=WAIT)
    assert clash.returncode == 2 and clash.stderr.count('\n') == 1, clash.stdout + clash.stderr
    assert '--foxglove 8765: the view serves on port 8765 too' in clash.stderr
    run = subprocess.run([str(BIN_DIR / 'bringup'), 'forward', '--duration', '1', '--real-time-factor', '0',
                          '--foxglove', '0'], capture_output=True, text=True, timeout=3 * WAIT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert re.search(r'^\[foxglove\] foxglove: ws://127\.0\.0\.1:\d+ ', run.stdout, re.M), run.stdout
    assert '[bringup] simulated 1.02 s' in run.stdout and 'Traceback' not in run.stdout + run.stderr
    assert processes_in_this_domain() == []


def test_the_help_says_how_and_what_it_costs():
    text = subprocess.run([str(BIN_DIR / 'foxglove'), '--help'], capture_output=True, text=True,
                          timeout=WAIT).stdout
    for words in ('--port', '--host', '127.0.0.1', '8765', 'Open connection', 'docs/foxglove_layout.json',
                  'only while a Foxglove panel shows it', 'camera/image_raw'):
        assert words in text, words
    bringup = subprocess.run([str(BIN_DIR / 'bringup'), '--help'], capture_output=True, text=True,
                             timeout=WAIT).stdout
    assert '--foxglove [PORT]' in bringup and 'only while an image' in bringup


def test_the_shipped_layout_is_the_generated_one():
    shipped = layout.DOCS_FILE.read_text()
    assert shipped == layout.layout_text(), 'regenerate: python -m epuck_ros.foxglove.layout'
    panels = json.loads(shipped)['configById']
    assert {name.split('!')[0] for name in panels} == {'3D', 'Image', 'Plot'}
    assert panels['3D!epuck']['layers']['epuck']['topic'] == layout.TOPICS['description']
    assert len(panels['Plot!proximity']['paths']) == 8
