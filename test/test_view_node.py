"""The view node over DDS without a browser: it follows the sim's robots and relays the page's actions to them."""
from __future__ import annotations

import http.client
import json
import math
import subprocess
from pathlib import Path

import pytest

from geometry_msgs.msg import Twist
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_ros2.decoder import DecoderFactory
from nav_msgs.msg import Odometry

from conftest import BIN_DIR


def _url(view) -> tuple[str, int]:
    view.wait_for_output('view: http://')
    line = next(line for line in view.output().splitlines() if line.startswith('view: http://'))
    host, port = line[len('view: http://'):].rstrip('/').rsplit(':', 1)
    return host, int(port)


def _call(address: tuple[str, int], method: str, path: str, body: dict | None = None) -> tuple[int, dict]:
    connection = http.client.HTTPConnection(*address, timeout=30)
    connection.request(method, path, body=None if body is None else json.dumps(body),
                       headers={'Content-Type': 'application/json'})
    response = connection.getresponse()
    result = response.status, json.loads(response.read())
    connection.close()
    return result


def test_view_follows_placed_robots_and_relays_step_and_drive(launch, test_node) -> None:
    names = ('epuck0', 'epuck1', 'epuck2')
    truth: dict[str, dict[int, tuple[float, float, float]]] = {name: {} for name in names}

    def keep(name: str, msg: Odometry) -> None:
        q = msg.pose.pose.orientation
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        truth[name][stamp] = (msg.pose.pose.position.x, msg.pose.pose.position.y, 2 * math.atan2(q.z, q.w))
    for name in names:
        test_node.node.create_subscription(Odometry, f'{name}/ground_truth', lambda m, n=name: keep(n, m), 100)
    driven = test_node.collect(Twist, 'epuck2/cmd_vel', 100)

    launch('sim', '--ros-args', '-p', 'paused:=true', '-p', 'robots:=3', '-p', 'seed:=5')
    address = _url(launch('view', '--ros-args', '-p', 'port:=0'))
    test_node.spin_until(lambda: [r['name'] for r in _call(address, 'GET', '/world')[1].get('robots', [])]
                         == list(names), what='the view to know the three placed robots', timeout=60)

    test_node.spin_until(lambda: _call(address, 'GET', '/state')[1]['paused'] is True,
                         what='the sim settings', timeout=60)
    # A page showing epuck1 in detail (polling for it): the view subscribes to epuck1's odometry and wheels only.
    assert _call(address, 'GET', '/state?robot=epuck1')[0] == 200
    for _ in range(10):  # until the test node's own subscriptions have matched and received a step
        status, answer = _call(address, 'POST', '/api/step', {})
        assert status == 200, answer
        stepped = round(float(answer['message'].split('t=')[1].split()[0]) * 1e9)
        test_node.spin_until(lambda: all(robot['stamp'] is not None and round(robot['stamp'] * 1e9) == stepped
                                         for robot in _call(address, 'GET', '/state')[1]['robots'].values()),
                             what='the view to hold the step', timeout=60)
        test_node.spin_for(0.2)
        if all(stepped in truth[name] for name in names):
            break
    assert all(stepped in truth[name] for name in names), 'the test node never received ground_truth of a step'
    robots = _call(address, 'GET', '/state')[1]['robots']
    for name in names:
        assert tuple(robots[name]['pose']) == truth[name][stepped]

    def details() -> dict:
        _call(address, 'POST', '/api/step', {})  # paused: the next step brings them
        return _call(address, 'GET', '/state?robot=epuck1')[1]['robots']
    test_node.spin_until(lambda: details()['epuck1']['wheel_speeds'] is not None,
                         what="epuck1's wheel speeds", timeout=60)
    robots = _call(address, 'GET', '/state?robot=epuck1')[1]['robots']
    assert robots['epuck1']['odom'] == [0.0, 0.0, 0.0] and robots['epuck1']['odom_error']['distance'] == 0.0
    assert robots['epuck1']['wheel_speeds'] == [0.0, 0.0]
    assert all('odom' not in robots[name] and 'wheel_speeds' not in robots[name] for name in ('epuck0', 'epuck2'))

    def drive() -> bool:  # re-sent, as the page does while a key is held: the view's new publisher must match first
        assert _call(address, 'POST', '/api/drive', {'robot': 'epuck2', 'linear': 0.05, 'angular': -0.5})[0] == 200
        return bool(driven)
    test_node.spin_until(drive, what='the Twist on epuck2/cmd_vel', timeout=60)
    assert (driven[-1].linear.x, driven[-1].angular.z) == (0.05, -0.5)
    status, answer = _call(address, 'POST', '/api/drive', {'robot': 'epuck7', 'linear': 0.0, 'angular': 0.0})
    assert status == 400 and 'epuck7' in answer['error']
    # The simulator's own parameter range decides what real-time factor it takes.
    status, answer = _call(address, 'POST', '/api/real_time_factor', {'value': 1e9})
    assert status == 400 and answer['error'].startswith('real_time_factor refused'), answer
    assert _call(address, 'POST', '/api/real_time_factor', {'value': 2})[0] == 200
    test_node.spin_until(lambda: _call(address, 'GET', '/state')[1]['real_time_factor'] == 2.0,
                         what='the new real-time factor back from the sim', timeout=60)


def test_a_port_in_use_is_one_line_and_exit_code_2(launch) -> None:
    address = _url(launch('view', '--ros-args', '-p', 'port:=0'))
    result = subprocess.run([str(BIN_DIR / 'view'), '--ros-args', '-p', f'port:={address[1]}'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert f'cannot serve on 127.0.0.1:{address[1]}' in result.stderr + result.stdout
    assert 'take any free port with -p port:=0' in result.stderr + result.stdout
    assert 'Traceback' not in result.stderr + result.stdout


def test_help_lists_the_parameters() -> None:
    result = subprocess.run([str(BIN_DIR / 'view'), '--help'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    for text in ('host', 'port', '8765', 'sim_node', 'example'):
        assert text in result.stdout


def without_topic(source: Path, target: Path, topic: str) -> Path:
    """The MCAP bag folder `source` copied to `target` without `topic`: schemas, channels (their QoS) and metadata
    records as they are, by the mcap library."""
    target.mkdir()
    with open(next(source.glob('*.mcap')), 'rb') as stream, open(target / 'copy_0.mcap', 'wb') as out:
        reader = make_reader(stream)
        header = reader.get_header()
        writer = Writer(out)
        writer.start(header.profile, header.library)
        schemas, channels = {}, {}
        for schema, channel, message in reader.iter_messages():
            if channel.topic == topic:
                continue
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(channel.topic, channel.message_encoding,
                                                               schemas[schema.id], channel.metadata)
            writer.add_message(channels[channel.id], message.log_time, message.data, message.publish_time)
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)
        writer.finish()
    return target


def test_view_draws_a_played_bag_recorded_before_ir_raw(launch, test_node, tmp_path) -> None:
    """`bag play` of a sample run without its `ir_raw` (as recorded before there was one) into the view: poses as
    recorded, IR rays from the 8 Range messages."""
    bag = without_topic(Path(__file__).resolve().parents[1] / 'bags' / 'avoid', tmp_path / 'avoid', '/ir_raw')
    poses, ranges = {}, {f'ps{i}': set() for i in range(8)}
    with open(next(bag.glob('*.mcap')), 'rb') as stream:  # read by mcap_ros2, not by our own reader
        read = list(make_reader(stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
            topics=['/ground_truth', '/proximity']))
    for _, channel, _, msg in read:
        if channel.topic == '/ground_truth':
            q, stamp = msg.pose.pose.orientation, msg.header.stamp
            poses[stamp.sec * 10**9 + stamp.nanosec] = [msg.pose.pose.position.x, msg.pose.pose.position.y,
                                                        2 * math.atan2(q.z, q.w)]
        else:
            ranges[msg.header.frame_id].add(round(min(msg.range, 0.07), 5))  # inf (nothing seen): full length

    address = _url(launch('view', '--ros-args', '-p', 'port:=0'))
    launch('bag', 'play', str(bag), '--rate', '2')

    def drawn() -> dict | None:
        robot = _call(address, 'GET', '/state')[1]['robots'].get('epuck')
        return robot if robot and robot['pose'] and robot['ir_range'] and robot['stamp'] > 1.0 else None
    test_node.spin_until(lambda: drawn() is not None, what='the played run in the view', timeout=60)
    robot = drawn()
    # The view's yaw from the quaternion may differ from the test's in the last bit (the order of operations).
    assert robot['pose'] == pytest.approx(poses[round(robot['stamp'] * 1e9)], abs=1e-12)
    for sensor, drawn_range in enumerate(robot['ir_range']):
        assert drawn_range in ranges[f'ps{sensor}']


def test_view_draws_a_played_swarm_bag_without_the_swarm_topic(launch, test_node) -> None:
    """`bag play` of the sample swarm run (five robots, recorded before the swarm topics: each robot's own topics
    only): with no `swarm/observation` publisher the view reads every robot's own ground truth."""
    bag = Path(__file__).resolve().parents[1] / 'bags' / 'swarm'
    poses: dict[str, dict[int, list[float]]] = {}
    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        for _, channel, _, msg in make_reader(stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            if channel.topic.endswith('/ground_truth'):
                q, stamp = msg.pose.pose.orientation, msg.header.stamp
                poses.setdefault(channel.topic.split('/')[1], {})[stamp.sec * 10**9 + stamp.nanosec] = [
                    msg.pose.pose.position.x, msg.pose.pose.position.y, 2 * math.atan2(q.z, q.w)]
    assert len(poses) == 5

    address = _url(launch('view', '--ros-args', '-p', 'port:=0'))
    launch('bag', 'play', str(bag), '--rate', '2')

    def drawn() -> dict | None:
        robots = _call(address, 'GET', '/state')[1]['robots']
        return robots if set(robots) == set(poses) and all(
            robot['pose'] and robot['stamp'] > 1.0 for robot in robots.values()) else None
    test_node.spin_until(lambda: drawn() is not None, what='every played robot in the view', timeout=60)
    for name, robot in drawn().items():
        assert robot['pose'] == pytest.approx(poses[name][round(robot['stamp'] * 1e9)], abs=1e-12)
