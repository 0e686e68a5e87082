"""The `bag` inspection CLI on synthetic e-puck runs: info, summary figures, plot, csv, and errors.

Runs are made with the course's wheel speeds and the exact-arc kinematics, so the expected
figures (a 0.078 m circle, 83° timed corners) come from the course, not from the code under test.
"""
from __future__ import annotations

import csv
import io
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Range
from std_msgs.msg import String

from epuck_ros.bag.export import export_csv
from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.reader import Bag
from epuck_ros.bag.run_summary import RunTally, load_run, load_runs, summarise, summarise_runs
from epuck_ros.bag.summary_text import format_figures
from epuck_ros.bag.writer import BagWriter
from epuck_ros.kinematics import integrate_arc, twist_from_wheels
from epuck_ros.model import MAX_WHEEL_SPEED, RobotModel
from epuck_ros.world import World, default_world

BAG = str(Path(sys.executable).parent / 'bag')
REPO = Path(__file__).resolve().parents[1]
STEP = 0.032
START_NS = 1_700_000_000 * 10**9
MODEL = RobotModel()
WALL_X = 0.5 - MODEL.body_radius
"""Where the body touches the +x wall of the default 1 m arena."""


def twist(left: float, right: float) -> tuple[float, float]:
    """Wheel speeds as fractions of MAX_SPEED, as the course writes them -> (v, w)."""
    return twist_from_wheels(left * MAX_WHEEL_SPEED, right * MAX_WHEEL_SPEED, MODEL)


def drive(segments: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
    """Poses every step for (left, right, seconds) segments, starting at the origin facing +x."""
    poses = [(0.0, 0.0, 0.0)]
    for left, right, seconds in segments:
        v, w = twist(left, right)
        for _ in range(round(seconds / STEP)):
            poses.append(tuple(float(c) for c in integrate_arc(*poses[-1], v, w, STEP)))
    return poses


def odometry(pose: tuple[float, float, float], step: int, frame: str) -> bytes:
    msg = Odometry(child_frame_id='base_link')
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(START_NS + step * 32_000_000, 10**9)
    msg.pose.pose.position.x, msg.pose.pose.position.y = pose[0], pose[1]
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
    return serialize_message(msg)


def ranges(step: int, nearest: dict[int, float]) -> list[bytes]:
    """Eight Range messages; sensor i reads nearest[i] or +inf (nothing in range)."""
    messages = []
    for i in range(8):
        msg = Range(radiation_type=Range.INFRARED, field_of_view=0.1, max_range=0.07,
                    range=nearest.get(i, math.inf))
        msg.header.frame_id = f'ps{i}'
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(START_NS + step * 32_000_000, 10**9)
        messages.append(serialize_message(msg))
    return messages


def write_run(path: Path, truth: list, odom: list | None = None, with_world: bool = True,
              proximity: dict[int, dict[int, float]] | None = None, world: World | None = None) -> Path:
    """A bag like the sim's: world (latched; the default one unless given), then per step odom, ground_truth,
    eight ranges."""
    writer = BagWriter(path)
    if with_world:
        writer.add_topic('/world', 'std_msgs/msg/String', [QosProfile(depth=1, durability='transient_local')])
        world = serialize_message(String(data=yaml.safe_dump((world or default_world()).to_dict())))
        writer.write('/world', world, START_NS)
    for topic in ('/odom', '/ground_truth'):
        writer.add_topic(topic, 'nav_msgs/msg/Odometry', [QosProfile()])
    writer.add_topic('/proximity', 'sensor_msgs/msg/Range', [QosProfile(depth=16)])
    for step, pose in enumerate(truth):
        stamp = START_NS + step * 32_000_000
        writer.write('/odom', odometry((odom or truth)[step], step, 'odom'), stamp)
        writer.write('/ground_truth', odometry(pose, step, 'world'), stamp)
        for data in ranges(step, (proximity or {}).get(step, {})):
            writer.write('/proximity', data, stamp)
    writer.close()
    return path


def run_bag(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([BAG, *args], capture_output=True, text=True, timeout=60)


def summary_of(path: Path):
    with Bag(path) as bag:
        return summarise(load_run(bag))


# --- info ------------------------------------------------------------------------------------------------

def test_info_prints_ros2_bag_info_fields_and_rates(tmp_path):
    path = write_run(tmp_path / 'circle', drive([(0.3, 0.6, 8.0)]))
    result = run_bag('info', str(path))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.split('\n')
    labels = [line.split(':')[0] for line in lines if line[:1].strip()]
    assert labels == ['Files', 'Bag size', 'Storage id', 'ROS Distro', 'Duration', 'Start', 'End',
                      'Messages', 'Topic information', 'Stamp gaps', 'Service', 'Service information']
    steps = round(8.0 / STEP) + 1
    fields = {line[:19].rstrip(': '): line[19:] for line in lines if line[:1].strip()}
    assert fields['Files'] == 'circle_0.mcap' and fields['Storage id'] == 'mcap'
    assert fields['Duration'] == f'{(steps - 1) * 32 // 1000}.{(steps - 1) * 32 % 1000:03d}000000s'
    assert fields['Start'].endswith('(1700000000.000000000)')
    assert fields['Messages'] == str(1 + 10 * steps)
    topic_lines = [line.strip() for line in lines if 'Topic: ' in line]
    assert topic_lines[0].startswith('Topic information: Topic: /ground_truth | Type: nav_msgs/msg/Odometry | '
                                     f'Count: {steps} | Serialization Format: cdr | Rate: 31.25 Hz')
    assert any(f'/proximity | Type: sensor_msgs/msg/Range | Count: {8 * steps} |' in line for line in topic_lines)


def test_info_flags_a_bag_that_was_not_closed(tmp_path):
    path = write_run(tmp_path / 'run', drive([(0.5, 0.5, 2.0)]))
    data = (path / 'run_0.mcap').read_bytes()
    (path / 'run_0.mcap').write_bytes(data[:len(data) - 200])  # no footer, no summary
    result = run_bag('info', str(path / 'run_0.mcap'))
    assert result.returncode == 0 and 'not closed properly' in result.stdout


# --- summary ---------------------------------------------------------------------------------------------

def test_summary_of_the_course_circle(tmp_path):
    duration = 312 * STEP
    path = write_run(tmp_path / 'circle', drive([(0.3, 0.6, duration)]), proximity={40: {0: 0.052, 7: 0.031}})
    summary = summary_of(path)
    v, _ = twist(0.3, 0.6)
    assert summary.circle.radius == pytest.approx(0.078, abs=1e-4)  # L/2 (wR+wL)/(wR-wL)
    assert summary.circle.centre == pytest.approx((0.0, 0.078), abs=1e-4)
    assert summary.corners is None
    assert summary.duration == pytest.approx(duration, abs=1e-9)
    assert summary.distance == pytest.approx(v * duration, rel=1e-4)  # chords of the arcs
    assert summary.mean_speed == pytest.approx(v, rel=1e-4)
    assert (summary.closest_approach, summary.closest_sensor) == (pytest.approx(0.031), 'ps7')
    assert summary.closest_time == pytest.approx(40 * STEP)
    assert (summary.collisions, summary.collisions_from) == (0, 'world')


@pytest.mark.parametrize('turn_seconds, corner_deg', [(1.0, 83.0), (1.084, 90.0)])
def test_summary_of_the_course_rectangle(tmp_path, turn_seconds, corner_deg):
    """FORWARD 5 s at 0.5, TURN at ±0.3: the course's timed 1 s turn makes 83° corners."""
    side = [(0.5, 0.5, 5.0), (-0.3, 0.3, turn_seconds)]
    path = write_run(tmp_path / 'rect', drive(side * 4 + [(0.5, 0.5, 1.0)]))
    summary = summary_of(path)
    assert summary.motion == 'rectangle' and summary.circle is None
    assert len(summary.corners.angles_deg) == 4
    # turns last whole steps: 31 or 34 steps of 1.449 rad/s
    assert summary.corners.angles_deg == pytest.approx([corner_deg] * 4, abs=1.5)
    assert summary.corners.side_lengths[:4] == pytest.approx([0.314] * 4, abs=0.005)


def test_a_rectangle_that_ends_on_its_last_turn_has_four_corners(tmp_path):
    """Four sides and four turns, as the rectangle behaviour drives it: the closing turn is the 4th corner."""
    path = write_run(tmp_path / 'rect', drive([(0.5, 0.5, 5.0), (0.3, -0.3, 1.084)] * 4 + [(0.0, 0.0, 2.0)]))
    summary = summary_of(path)
    assert summary.motion == 'rectangle'
    assert summary.corners.angles_deg == pytest.approx([-90.0] * 4, abs=1.5)
    assert summary.corners.side_lengths == pytest.approx([0.314] * 4, abs=0.005)


@pytest.mark.parametrize('segments, motion', [
    ([(0.0, 0.0, 3.0)], 'standing'),
    ([(0.5, 0.5, 6.0)], 'straight line'),
    ([(-0.5, 0.5, 4.0)], 'spin in place'),
    ([(0.3, 0.6, 10.0)], 'circle'),
    # avoid-like: straight runs broken by turns of assorted sizes, both ways
    ([(0.5, 0.5, 4.0), (0.5, -0.5, 0.4), (0.5, 0.5, 3.0), (-0.5, 0.5, 1.3), (0.5, 0.5, 0.6),
      (0.5, -0.5, 0.9), (0.5, 0.5, 2.0)], 'free motion'),
])
def test_summary_gives_only_the_figures_of_the_run_s_shape(tmp_path, segments, motion):
    summary = summary_of(write_run(tmp_path / 'run', drive(segments)))
    assert summary.motion == motion
    shapes = {'straight line': 'straight', 'spin in place': 'spin', 'circle': 'circle', 'rectangle': 'corners'}
    for kind, name in shapes.items():
        assert (getattr(summary, name) is not None) == (kind == motion), name
    if motion == 'spin in place':
        _, w = twist(-0.5, 0.5)  # w = R/L (wR - wL)
        assert summary.spin.heading_rate == pytest.approx(w, rel=1e-6)
        assert summary.spin.turns == pytest.approx(w * 4.0 / (2 * math.pi), rel=0.01)
    if motion == 'straight line':
        v, _ = twist(0.5, 0.5)
        assert summary.straight.length == pytest.approx(v * round(6.0 / STEP) * STEP, rel=1e-9)
        assert summary.straight.heading_deg == pytest.approx(0.0) and summary.straight.max_deviation < 1e-9


@pytest.mark.parametrize('bag, motion, label, absent', [
    ('forward', 'straight line', 'Straight line:', ('Corners', 'Circle fit', 'Heading rate')),
    ('spin', 'spin in place', 'Heading rate:', ('Corners', 'Circle fit', 'Straight line')),
    ('circle', 'circle', 'Circle fit:        radius 0.0780 m', ('Corners', 'Heading rate')),
    ('rectangle', 'rectangle', 'Corners:           4: ', ('Circle fit', 'Heading rate')),
    ('avoid', 'free motion', 'Closest approach:', ('Corners', 'Circle fit', 'Heading rate', 'Straight line')),
])
def test_summary_of_the_sample_bags(bag, motion, label, absent):
    result = run_bag('summary', str(REPO / 'bags' / bag))
    assert result.returncode == 0, result.stderr
    assert f'Motion:            {motion}\n' in result.stdout and label in result.stdout
    for word in absent:
        assert word not in result.stdout
    if bag == 'rectangle':
        corners = result.stdout.split('Corners:')[1].split('(')[0]
        assert [float(a) for a in corners.split(':')[1].replace('°', '').split(',')] == pytest.approx([90] * 4, abs=2)


def into_the_wall() -> tuple[list, list]:
    """Drive at the +x wall, back off, drive into it again: the true pose stops at the wall, odometry does not."""
    odom = drive([(0.5, 0.5, 9.0), (-0.5, -0.5, 1.0), (0.5, 0.5, 2.0)])
    truth = [odom[0]]
    for before, after in zip(odom, odom[1:]):
        truth.append((min(truth[-1][0] + after[0] - before[0], WALL_X), 0.0, 0.0))
    return truth, odom


@pytest.mark.parametrize('with_world, source', [(True, 'world'), (False, 'odom vs ground_truth')])
def test_summary_counts_each_contact_once(tmp_path, with_world, source):
    truth, odom = into_the_wall()
    path = write_run(tmp_path / 'wall', truth, odom, with_world=with_world)
    summary = summary_of(path)
    assert (summary.collisions, summary.collisions_from) == (2, source)
    assert summary.corners is None  # backing off on the same heading is not a corner


def test_summary_json_is_machine_readable(tmp_path):
    path = write_run(tmp_path / 'circle', drive([(0.3, 0.6, 10.0)]))
    result = run_bag('summary', '--json', str(path))
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert data['circle']['radius'] == pytest.approx(0.078, abs=1e-4)
    assert data['closest_approach'] is None and data['trajectory_topic'] == '/ground_truth'


# --- plot and csv ----------------------------------------------------------------------------------------

@pytest.mark.parametrize('with_world', [True, False])
def test_plot_writes_a_png(tmp_path, with_world):
    truth, odom = into_the_wall()
    path = write_run(tmp_path / 'wall', truth, odom, with_world=with_world)
    result = run_bag('plot', str(path), '-o', str(tmp_path / 'run.png'))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / 'run.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_csv_flattens_any_topic(tmp_path):
    poses = drive([(0.5, 0.5, 1.0)])
    path = write_run(tmp_path / 'run', poses, proximity={3: {2: 0.05}})
    output = io.StringIO()
    with Bag(path) as bag:
        assert export_csv(bag, '/ground_truth', output) == len(poses)
    rows = list(csv.DictReader(io.StringIO(output.getvalue())))
    assert list(rows[0])[:5] == ['log_time', 'publish_time', 'header.stamp', 'header.frame_id', 'child_frame_id']
    assert rows[3]['header.stamp'] == rows[3]['log_time'] == '1700000000.096000000'
    assert float(rows[-1]['pose.pose.position.x']) == poses[-1][0]
    assert 'pose.covariance[35]' in rows[0] and 'twist.twist.angular.z' in rows[0]

    result = run_bag('csv', str(path), '/proximity', '-o', str(tmp_path / 'ranges.csv'))
    assert result.returncode == 0, result.stderr
    rows = list(csv.DictReader((tmp_path / 'ranges.csv').open()))
    assert len(rows) == 8 * len(poses)
    assert [(r['header.frame_id'], r['range']) for r in rows[24:27]] == [('ps0', 'inf'), ('ps1', 'inf'),
                                                                         ('ps2', '0.05')]


# --- errors ----------------------------------------------------------------------------------------------

def only_ranges(path: Path) -> Path:
    writer = BagWriter(path)
    writer.add_topic('/proximity', 'sensor_msgs/msg/Range', [QosProfile()])
    for data in ranges(0, {}):
        writer.write('/proximity', data, START_NS)
    writer.close()
    return path


@pytest.mark.parametrize('case, command, message', [
    ('missing', 'info', 'no such bag folder or file'),
    ('not_mcap', 'info', 'not an MCAP file'),
    ('truncated', 'summary', 'truncated MCAP file'),
    ('empty_folder', 'info', 'no .mcap file'),
    ('no_odometry', 'summary', 'no odometry'),
    ('no_odometry', 'plot', 'no odometry'),
    ('unknown_topic', 'csv', 'no topic /nope'),
])
def test_unusable_input_is_one_line_and_exit_code_2(tmp_path, case, command, message):
    paths = {'missing': tmp_path / 'nothing_here', 'not_mcap': tmp_path / 'notes.mcap',
             'truncated': tmp_path / 'cut.mcap', 'empty_folder': tmp_path / 'empty'}
    paths['not_mcap'].write_text('this is not a bag\n')
    paths['truncated'].write_bytes(b'\x89MCAP0\r\n\x01\x10')
    paths['empty_folder'].mkdir()
    path = paths.get(case) or only_ranges(tmp_path / 'ranges')
    extra = {'plot': ['-o', str(tmp_path / 'x.png')], 'csv': ['/nope']}.get(command, [])
    result = run_bag(command, str(path), *extra)
    assert result.returncode == 2
    assert result.stdout == ''
    assert result.stderr.count('\n') == 1 and message in result.stderr and str(path) in result.stderr


# --- several robots ----------------------------------------------------------------------------------------

SWARM_STARTS = {'epuck0': (-0.2, 0.0, 0.0), 'epuck1': (0.2, 0.0, math.pi), 'epuck2': (0.0, 0.3, math.pi / 2)}
SPEED_PER_STEP = 0.0016
"""m per 32 ms step (0.05 m/s)."""


def ramp(start: float, end: float) -> list[float]:
    steps = max(1, round(abs(end - start) / SPEED_PER_STEP))
    return [start + (end - start) * k / steps for k in range(1, steps + 1)]


def swarm_motion() -> dict[str, list[float]]:
    """How far each robot has driven ahead along its heading, per step.

    epuck0 and epuck1 drive at each other until their bodies touch, back off, and touch again: 2 contacts
    between robots. epuck2 drives into the +y wall and stays there: 1 contact with a wall.
    """
    touch = 0.2 - MODEL.body_radius  # each drives this far: centres 2 body radii apart
    ahead = [0.0] + ramp(0.0, touch) + [touch] * 10 + ramp(touch, 0.1) + ramp(0.1, touch) + [touch] * 10
    to_wall = 0.5 - MODEL.body_radius - 0.3
    wall = [0.0] + [min(k * SPEED_PER_STEP, to_wall) for k in range(1, len(ahead))]
    return {'epuck0': ahead, 'epuck1': ahead, 'epuck2': wall}


def swarm_pose(name: str, ahead: float) -> tuple[float, float, float]:
    x, y, yaw = SWARM_STARTS[name]
    return x + ahead * math.cos(yaw), y + ahead * math.sin(yaw), yaw


def write_swarm(path: Path, starts: dict[str, tuple[float, float, float]] | None = None,
                motion: dict[str, list[float]] | None = None) -> Path:
    """A bag as the multi-robot sim records it: the world (robots list), then per step each robot's
    <name>/odom (in its odom frame: from (0, 0, 0) at its start pose) and <name>/ground_truth."""
    starts = starts or SWARM_STARTS
    motion = motion or swarm_motion()
    writer = BagWriter(path)
    writer.add_topic('/world', 'std_msgs/msg/String', [QosProfile(depth=1, durability='transient_local')])
    world = {'arena': {'size': [1.0, 1.0]},
             'robots': [{'name': name, 'start': list(pose)} for name, pose in starts.items()]}
    writer.write('/world', serialize_message(String(data=yaml.safe_dump(world))), START_NS)
    for name in starts:
        for topic in ('odom', 'ground_truth'):
            writer.add_topic(f'/{name}/{topic}', 'nav_msgs/msg/Odometry', [QosProfile()])
    for step in range(len(next(iter(motion.values())))):
        stamp = START_NS + step * 32_000_000
        for name, (x, y, yaw) in starts.items():
            ahead = motion[name][step]
            truth = (x + ahead * math.cos(yaw), y + ahead * math.sin(yaw), yaw)
            writer.write(f'/{name}/odom', odometry((ahead, 0.0, 0.0), step, f'{name}/odom'), stamp)
            writer.write(f'/{name}/ground_truth', odometry(truth, step, 'world'), stamp)
    writer.close()
    return path


def test_summary_reports_each_robot_and_contacts_between_robots(tmp_path):
    path = write_swarm(tmp_path / 'swarm')
    motion = swarm_motion()
    with Bag(path) as bag:
        runs = load_runs(bag)
    summary = summarise_runs(runs)
    assert [r.namespace for r in summary.robots] == ['/epuck0', '/epuck1', '/epuck2']
    assert [(r.collisions, r.robot_collisions) for r in summary.robots] == [(0, 2), (0, 2), (1, 0)]
    assert summary.robot_robot_contacts == 2
    for robot in summary.robots:
        ahead = motion[robot.namespace[1:]]
        assert robot.distance == pytest.approx(sum(abs(b - a) for a, b in zip(ahead, ahead[1:])), rel=1e-9)
    for run in runs:  # odometry from the start pose in the world file lands on the true path
        odom = run.odom_in_world()
        assert odom.x == pytest.approx(run.truth.x, abs=1e-12) and odom.y == pytest.approx(run.truth.y, abs=1e-12)
    contact = next(c for c in summary.contacts if c.kind == 'robot')
    assert (contact.robot, contact.other) == ('epuck0', 'epuck1')
    assert contact.x == pytest.approx(-MODEL.body_radius, abs=SPEED_PER_STEP)

    result = run_bag('summary', str(path))
    assert result.returncode == 0, result.stderr
    assert 'Robots:            3\n' in result.stdout
    assert '1 with walls/obstacles (from world), 2 between robots' in result.stdout
    rows = [line.split() for line in result.stdout.split('\n') if line.startswith('/epuck')]
    assert [(row[0], row[3], row[4]) for row in rows] == [('/epuck0', '0', '2'), ('/epuck1', '0', '2'),
                                                          ('/epuck2', '1', '0')]
    data = json.loads(run_bag('summary', '--json', str(path)).stdout)
    assert data['robot_robot_contacts'] == 2 and len(data['robots']) == 3
    one = run_bag('summary', str(path), '--namespace', 'epuck2')
    assert 'Robot:             /epuck2' in one.stdout and '1 with walls/obstacles, 0 with robots' in one.stdout


def test_the_tally_fed_live_agrees_with_the_bag_summary(tmp_path):
    """The `bringup` command feeds RunTally the ground truth as it arrives; the figures must be the bag summary's."""
    path = write_swarm(tmp_path / 'swarm')
    with Bag(path) as bag:
        runs = load_runs(bag)
        summary = summarise_runs(runs)
    live = RunTally(list(SWARM_STARTS), runs[0].world, MODEL.body_radius)
    samples = [(int(stamp), run.name, float(x), float(y), float(yaw)) for run in runs
               for stamp, x, y, yaw in zip(run.truth.stamps_ns, run.truth.x, run.truth.y, run.truth.yaw)]
    lost = samples.pop(40)  # a sample lost on the way: that stamp is skipped for robot-robot contacts
    for stamp, name, x, y, yaw in sorted(samples, key=lambda s: s[0]):
        live.add(name, stamp, x, y, yaw)
    for figures, robot in zip(live.figures, summary.robots):
        assert figures.world_contacts == robot.collisions and figures.robot_contacts == robot.robot_collisions
        assert figures.final_pose == robot.final_pose
        if figures.name != lost[1]:
            assert figures.distance == robot.distance
    assert live.robot_robot_contacts == 2
    assert format_figures(live.figures).split('\n')[2].startswith('epuck2: ')


def test_csv_takes_any_robot_s_topic(tmp_path):
    path = write_swarm(tmp_path / 'swarm')
    steps = len(swarm_motion()['epuck2'])
    for topic in ('/epuck2/ground_truth', 'epuck2/ground_truth'):
        result = run_bag('csv', str(path), topic)
        assert result.returncode == 0, result.stderr
        rows = list(csv.DictReader(io.StringIO(result.stdout)))
        assert len(rows) == steps
        assert float(rows[-1]['pose.pose.position.y']) == pytest.approx(0.5 - MODEL.body_radius)


# --- help and arguments ------------------------------------------------------------------------------------

@pytest.mark.parametrize('command', ['info', 'summary', 'plot', 'csv', 'play'])
def test_every_subcommand_s_help_shows_an_example(command):
    result = run_bag(command, '--help')
    assert result.returncode == 0
    assert 'example' in result.stdout and f'bag {command} bags/' in result.stdout


def test_plot_to_an_unsupported_format_is_one_line_and_exit_2(tmp_path):
    result = run_bag('plot', str(REPO / 'bags' / 'forward'), '-o', str(tmp_path / 'out.txt'))
    assert result.returncode == 2 and result.stdout == ''
    assert result.stderr.count('\n') == 1 and 'out.txt' in result.stderr and '.png' in result.stderr
    assert not (tmp_path / 'out.txt').exists()
