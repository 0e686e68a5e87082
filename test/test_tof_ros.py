"""The ToF over ROS and in Webots scripts: the `tof` topic (sensor_msgs/Range as webots_ros2's e-puck publishes it)
from the real `sim` process, and `robot.getDevice('tof')` headless and through `webots_controller`, against the
core and the closed form (the lookup table of the distance along the ray)."""
from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from sensor_msgs.msg import Range

from conftest import EVERY_MESSAGE, ros_args
from epuck_ros.experiments.trial import Script, Trial, run
from epuck_ros.model import TOF_LOOKUP_TABLE, TOF_POSE
from epuck_ros.sensors import tof
from epuck_ros.simulation import Simulation
from epuck_ros.world import load_world
from test_headless_scripts import clean_imports  # noqa: F401 - a fixture
from test_webots import ControllerRun

X, Y, _, YAW = TOF_POSE
FACE_X = 0.3
"""The wall's face in the worlds here: the robot starts at the origin facing it."""


def wall_world(tmp_path: Path, robots: int = 1) -> Path:
    world = tmp_path / 'wall.yaml'
    placed = ({'robot': {'start': [0.0, 0.0, 0.0]}} if robots == 1 else
              {'robots': [{'name': f'epuck{i}', 'start': [0.0, 0.3 * i - 0.15, 0.0]} for i in range(robots)]})
    world.write_text(yaml.safe_dump({'arena': {'size': [1.0, 1.0]}, **placed,
                                     'boxes': [{'position': [FACE_X + 0.05, 0.0], 'size': [0.1, 0.8]}]}))
    return world


@pytest.mark.parametrize('robots', [1, 2])
def test_tof_topic_is_webots_range_of_the_cores_value(launch: object, test_node: object, tmp_path: Path,
                                                      robots: int) -> None:
    """A reader on `tof` (`epuckN/tof` with several robots) makes the sim compute it: each message is the Range
    webots_ros2 fills (INFRARED, fov the aperture 0.44, 0 to 2 m, frame `tof` prefixed as the robot's other frames)
    whose range is the core's value back through the table, stamped with its step."""
    world = wall_world(tmp_path, robots)
    prefixes = [''] if robots == 1 else [f'epuck{i}/' for i in range(robots)]
    received = {prefix: test_node.collect(Range, prefix + 'tof', EVERY_MESSAGE) for prefix in prefixes}
    launch('sim', *ros_args({'world': str(world), 'real_time_factor': 0.0, 'noise': False}))
    test_node.wait_for_simulator()
    test_node.spin_until(lambda: all(len(messages) > 3 for messages in received.values()), timeout=30.0,
                         what='the tof topics')   # no command: the robots stand still, every step reads the same
    core = Simulation(load_world(world), noise=False)
    core.senses.want('tof', range(robots))
    for index, prefix in enumerate(prefixes):
        msg = received[prefix][-1]
        assert msg.header.frame_id == prefix + 'tof'
        assert (msg.radiation_type, msg.field_of_view, msg.min_range, msg.max_range) == \
            (Range.INFRARED, float(np.float32(0.44)), 0.0, 2.0)
        assert msg.range == float(np.float32(tof.range_from_value(core.senses.tof[index])))
        assert msg.range == pytest.approx(FACE_X - X, abs=1e-6)   # the face is 0.266 m ahead of the sensor
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in received[prefix]]
        assert all(round(t / 0.032) * 0.032 == pytest.approx(t, abs=1e-9) for t in stamps)   # each a step's time


TOF_PROBE = '''
import json
from controller import Robot

robot = Robot()
step = int(robot.getBasicTimeStep())
sensor = robot.getDevice('tof')
sensor.enable(step)
for name in ('left wheel motor', 'right wheel motor'):
    robot.getDevice(name).setPosition(float('inf'))
    robot.getDevice(name).setVelocity(-2.0)
print('TOF', json.dumps({'t': robot.getTime(), 'v': sensor.getValue(), 'aperture': sensor.getAperture(),
                         'table': sensor.getLookupTable()}), flush=True)
while robot.step(step) != -1:
    print('TOF', json.dumps({'t': robot.getTime(), 'v': sensor.getValue()}), flush=True)
'''


def probes(text: str) -> list[dict]:
    return [json.loads(line.split(' ', 1)[1]) for line in text.splitlines() if line.startswith('TOF ')]


def headless_probe(script: Path, world: Path, noise: bool, capsys: pytest.CaptureFixture
                   ) -> tuple[list[dict], dict[int, np.ndarray]]:
    """The probe's readings and the true pose of every step (by ms), in a headless trial of 3 s."""
    poses: dict[int, np.ndarray] = {}
    run(Trial(Script(str(script)), world=str(world), duration=3.0, noise=noise, seed=4),
        each_step=lambda sim: poses.__setitem__(round(sim.time * 1000), sim.true_pose[0].copy()))
    return probes(capsys.readouterr().out), poses


def test_tof_device_headless_reads_the_table_of_the_distance_along_its_ray(
        tmp_path: Path, capsys: pytest.CaptureFixture, clean_imports: None) -> None:  # noqa: F811
    """Backing away from a wall, noise off: NaN before the first period, then each step the table's value for the
    distance along the ray at that step's true pose (as the topic carries it: `tof.carried`)."""
    script = tmp_path / 'tof_probe.py'
    script.write_text(textwrap.dedent(TOF_PROBE))
    readings, poses = headless_probe(script, wall_world(tmp_path), False, capsys)
    first = readings[0]
    assert math.isnan(first['v']) and first['aperture'] == 0.44
    assert first['table'] == TOF_LOOKUP_TABLE.ravel().tolist()
    for reading in readings[1:]:
        x, y, yaw = poses[round(reading['t'] * 1000)]
        ox = x + X * math.cos(yaw) - Y * math.sin(yaw)
        along = (FACE_X - ox) / math.cos(yaw + YAW)
        expected = tof.carried(float(np.interp(along, TOF_LOOKUP_TABLE[:, 0], TOF_LOOKUP_TABLE[:, 1])))
        assert reading['v'] == pytest.approx(expected, rel=1e-9), reading
    assert len(readings) >= 90 and readings[-1]['v'] > readings[1]['v'] + 50   # it backed away: 0.266 -> 0.39 m


def test_tof_device_over_ros_reads_what_it_reads_headless(launch: object, test_node: object, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture,
                                                          clean_imports: None) -> None:  # noqa: F811
    """Noise on, seed 4, lockstep: `webots_controller` over the `tof` topic reads, step for step, the very values
    the same script reads headless (the Range's float32 range and back on both paths)."""
    script = tmp_path / 'tof_probe.py'
    script.write_text(textwrap.dedent(TOF_PROBE))
    world = wall_world(tmp_path)
    headless, _ = headless_probe(script, world, True, capsys)
    controller = ControllerRun(launch, test_node, script, 3.0, noise=True, world=world, sim_params={'seed': 4})
    controller.finish()
    assert controller.stop_controller() == 0, controller.output
    over_ros = {round(p['t'] * 1000): p['v'] for p in probes(controller.output)[1:]}
    compared = [(over_ros[round(p['t'] * 1000)], p['v']) for p in headless[1:] if round(p['t'] * 1000) in over_ros]
    assert len(compared) >= 90
    assert all(a == b for a, b in compared), compared[:5]


TOF_AND_GPS = '''
from controller import Robot
robot = Robot()
tof, gps = robot.getDevice('tof'), robot.getDevice('gps')
tof.enable(32)
gps.enable(32)
for name in ('left wheel motor', 'right wheel motor'):
    robot.getDevice(name).setPosition(float('inf'))
    robot.getDevice(name).setVelocity(4.0)
while robot.step(32) != -1:
    if tof.getValue() < 90.0:   # about 12 cm from the wall: turn away
        robot.getDevice('left wheel motor').setVelocity(-2.0)
'''


def test_a_headless_tof_scripts_bag_is_the_bringup_bag_of_the_same_run(tmp_path: Path) -> None:
    """A script reading its tof and a turret GPS (noise on, seed 6, 3 s): `webots_controller --headless --record`
    writes the `tof` topic (from the step the script asked for it on) and every other topic as `bringup --controller
    --record` does over ROS, message for message."""
    from test_bag_headless import compare, read, run_both
    script = tmp_path / 'tof_and_gps.py'
    script.write_text(textwrap.dedent(TOF_AND_GPS))
    world = tmp_path / 'world.yaml'
    world.write_text(yaml.safe_dump({'arena': {'size': [0.6, 0.6]}, 'robot': {'start': [0.0, 0.0, 0.0],
                                                                              'turret': ['GPS']}}))
    options = ['--seed', '6', '--duration', '3', '--world', str(world)]
    ros = [read(bag) for bag in run_both(tmp_path, ['--controller', str(script), *options],
                                         ['webots_controller', str(script), '--headless', *options, '--record',
                                          str(tmp_path / 'headless')])]
    headless = read(tmp_path / 'headless')
    assert {'/tof', '/ground_truth'} <= set(headless)
    first = headless['/tof']['messages'][0]
    assert (first.header.stamp.sec, first.header.stamp.nanosec) == (0, 32_000_000)
    assert first.header.frame_id == 'tof' and first.radiation_type == Range.INFRARED
    ranges = [msg.range for msg in headless['/tof']['messages']]
    assert min(ranges) < 0.15 < max(ranges)   # it drove up to the wall
    for over_ros in ros:
        compare(over_ros, headless)
