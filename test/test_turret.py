"""The turret slot (issue 32 item 4): world files that give a robot a GPS, Compass and InertialUnit, their values
against Webots' closed forms (ENU, WorldInfo's defaults), a student's wall follower that imports `from controller
import Robot, GPS` run unchanged headless and through `webots_controller` over ROS (the same numbers both ways), and
the one-line refusal of a device the world does not give."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from epuck_ros.experiments.trial import Script, Trial, run
from epuck_ros.model import TURRET_SLOT
from epuck_ros.sensors import turret
from epuck_ros.world import TurretDevice, WorldError, default_world, load_world, world_from_dict, world_from_yaml
from test_headless_scripts import clean_imports  # noqa: F401 - a fixture
from test_webots import ControllerRun

# --- world files ----------------------------------------------------------------------------------------------------


def test_turret_forms_round_trip_and_old_worlds_keep_their_meaning():
    world = world_from_dict({'robots': [
        {'name': 'a', 'start': [0, 0, 0], 'turret': ['GPS', 'compass', {'type': 'inertial_unit', 'name': 'imu'}]},
        {'name': 'b', 'start': [0.3, 0, 0]}]})
    assert world.robots[0].turret == (TurretDevice('GPS', 'gps'), TurretDevice('Compass', 'compass'),
                                      TurretDevice('InertialUnit', 'imu'))
    assert world.robots[1].turret == ()
    data = world.to_dict()
    assert data['robots'][0]['turret'] == ['GPS', 'Compass', {'type': 'InertialUnit', 'name': 'imu'}]
    assert 'turret' not in data['robots'][1]
    assert world_from_yaml(yaml.safe_dump(data)) == world
    one = world_from_dict({'robot': {'start': [0.1, 0, 0], 'turret': ['Inertial Unit']}})
    assert one.to_dict()['robot'] == {'start': [0.1, 0.0, 0.0], 'turret': ['InertialUnit']}
    assert default_world().to_dict() == world_from_dict(default_world().to_dict()).to_dict()
    assert 'turret' not in yaml.safe_dump(default_world().to_dict())


@pytest.mark.parametrize('robot, field, problem', [
    ({'start': [0, 0, 0], 'turret': 'GPS'}, 'robot.turret', 'expected a list of devices'),
    ({'start': [0, 0, 0], 'turret': ['gyroscope']}, 'robot.turret[0]', 'expected a turret device, one of GPS'),
    ({'start': [0, 0, 0], 'turret': [7]}, 'robot.turret[0]', 'expected a turret device'),
    ({'start': [0, 0, 0], 'turret': [{'name': 'x'}]}, 'robot.turret[0].type', 'missing'),
    ({'start': [0, 0, 0], 'turret': [{'type': 'GPS', 'nmae': 'x'}]}, 'robot.turret[0]', "unknown key 'nmae'"),
    ({'start': [0, 0, 0], 'turret': [{'type': 'GPS', 'name': ''}]}, 'robot.turret[0].name', 'expected a device name'),
    ({'start': [0, 0, 0], 'turret': [{'type': 'GPS', 'name': 'a\nb'}]}, 'robot.turret[0].name', 'printable'),
    ({'start': [0, 0, 0], 'turret': ['GPS', {'type': 'GPS'}]}, 'robot.turret[1]', "a second device named 'gps'"),
])
def test_bad_turrets_are_named_by_file_and_field(tmp_path: Path, robot: dict, field: str, problem: str):
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump({'robot': robot}))
    with pytest.raises(WorldError) as error:
        load_world(path)
    assert str(error.value).startswith(f'{path}: {field}: ') and problem in str(error.value)


# --- values: Webots' closed forms -----------------------------------------------------------------------------------

@pytest.mark.parametrize('yaw', [0.0, 0.7, math.pi / 2, 2.9, -2.0])
def test_values_are_webots_closed_forms(yaw: float):
    """GPS: the slot's position in the world and the body's velocity there; Compass: north (+y in ENU) in the robot's
    frame; InertialUnit: yaw from +x, counter-clockwise, and the rotation's quaternion [x, y, z, w]."""
    x, y, v, w = 0.12, -0.3, 0.05, 0.8
    truth = turret.Truth.of((x, y, yaw), (v, w))
    sx, _, sz = TURRET_SLOT
    assert turret.gps_values(truth) == pytest.approx([x + sx * math.cos(yaw), y + sx * math.sin(yaw), sz], abs=1e-15)
    # v along the heading plus w x r, r = the slot 9.5 mm behind the axle: (v cos + 0.0095 w sin, v sin - 0.0095 w cos)
    assert turret.gps_speed_vector(truth) == pytest.approx(
        [v * math.cos(yaw) - sx * w * math.sin(yaw), v * math.sin(yaw) + sx * w * math.cos(yaw), 0.0], abs=1e-15)
    assert turret.compass_values(truth) == pytest.approx([math.sin(yaw), math.cos(yaw), 0.0], abs=1e-15)
    assert turret.roll_pitch_yaw(truth) == pytest.approx([0.0, 0.0, yaw], abs=1e-15)
    assert turret.quaternion(truth) == pytest.approx([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)], abs=1e-15)


def test_facing_north_the_compass_points_ahead():
    assert turret.compass_values(turret.Truth.of((0.0, 0.0, math.pi / 2), (0.0, 0.0))) == pytest.approx(
        [1.0, 0.0, 0.0], abs=1e-15)


# --- scripts --------------------------------------------------------------------------------------------------------

WALL_FOLLOWER = '''
"""A left-hand wall follower, as students write them: the IR ring for the wall, the GPS to log where it is."""
from controller import Robot, GPS

TIME_STEP = 64
MAX_SPEED = 6.28

robot = Robot()
ps = []
for i in range(8):
    ps.append(robot.getDevice('ps' + str(i)))
    ps[i].enable(TIME_STEP)
gps = robot.getDevice('gps')
gps.enable(TIME_STEP)
left_motor = robot.getDevice('left wheel motor')
right_motor = robot.getDevice('right wheel motor')
left_motor.setPosition(float('inf'))
right_motor.setPosition(float('inf'))
left_motor.setVelocity(0.0)
right_motor.setVelocity(0.0)

while robot.step(TIME_STEP) != -1:
    values = [sensor.getValue() for sensor in ps]
    front_wall = values[7] > 80 or values[0] > 80
    left_wall = values[5] > 80
    left_corner = values[6] > 80
    left_speed = right_speed = MAX_SPEED / 2
    if front_wall:
        left_speed, right_speed = MAX_SPEED / 2, -MAX_SPEED / 2
    elif left_wall:
        left_speed, right_speed = MAX_SPEED / 2, MAX_SPEED / 2
    elif left_corner:
        left_speed, right_speed = MAX_SPEED / 2, MAX_SPEED / 8
    else:
        left_speed, right_speed = MAX_SPEED / 8, MAX_SPEED / 2
    left_motor.setVelocity(left_speed)
    right_motor.setVelocity(right_speed)
    position = gps.getValues()
    print('GPS', repr(robot.getTime()), repr(position[0]), repr(position[1]), repr(position[2]), flush=True)
'''

PROBE = '''
from controller import Robot, Compass, InertialUnit
robot = Robot()
compass, imu = robot.getDevice('compass'), robot.getDevice('imu')
gps = robot.getGPS('gps')
for device in (compass, imu, gps):
    device.enable(32)
print('TURRET', repr([gps.getValues(), compass.getValues(), imu.getRollPitchYaw(), imu.getQuaternion()]))
robot.getDevice('left wheel motor').setPosition(float('inf'))
robot.getDevice('right wheel motor').setPosition(float('inf'))
robot.getDevice('left wheel motor').setVelocity(-1.0)
robot.getDevice('right wheel motor').setVelocity(2.0)
while robot.step(32) != -1:
    print('TURRET', repr([robot.getTime(), gps.getValues(), gps.getSpeedVector(), compass.getValues(),
                          imu.getRollPitchYaw(), imu.getQuaternion()]), flush=True)
'''


def turret_world(tmp_path: Path, turret_items: list | None) -> Path:
    path = tmp_path / 'turret.yaml'
    robot = {'start': [-0.3, 0.44, 0.0], **({'turret': turret_items} if turret_items is not None else {})}
    path.write_text(yaml.safe_dump({'arena': {'size': [1.0, 1.0]}, 'robot': robot}))
    return path


def gps_lines(text: str) -> list[tuple[float, ...]]:
    return [tuple(float(v) for v in line.split()[1:]) for line in text.splitlines() if line.startswith('GPS ')]


def headless(script: Path, world: Path, duration: float, capsys: pytest.CaptureFixture
             ) -> tuple[str, dict[int, np.ndarray]]:
    """The script's output and the true pose and twist (x, y, yaw, v, w) of every step (by ms) of a headless run."""
    states: dict[int, np.ndarray] = {}
    run(Trial(Script(str(script)), world=str(world), duration=duration, noise=False),
        each_step=lambda sim: states.__setitem__(round(sim.time * 1000),
                                                 np.r_[sim.true_pose[0], sim.true_twist[0]]))
    return capsys.readouterr().out, states


def test_turret_devices_headless_read_the_true_state_of_their_step(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                                   clean_imports: None) -> None:  # noqa: F811
    """Each device reads NaN before the first sampling period, then every step each device's value for that step's
    true state."""
    script = tmp_path / 'probe.py'
    script.write_text(textwrap.dedent(PROBE))
    world = turret_world(tmp_path, ['GPS', 'Compass', {'type': 'InertialUnit', 'name': 'imu'}])
    out, states = headless(script, world, 1.0, capsys)
    readings = [eval(line.split(' ', 1)[1], {'nan': math.nan}) for line in out.splitlines()
                if line.startswith('TURRET ')]
    assert all(math.isnan(value) for values in readings[0] for value in values)
    for t, *values in readings[1:]:
        x, y, yaw, v, w = states[round(t * 1000)]
        truth = turret.Truth.of((x, y, yaw), (v, w))
        assert values == [turret.gps_values(truth), turret.gps_speed_vector(truth), turret.compass_values(truth),
                          turret.roll_pitch_yaw(truth), turret.quaternion(truth)]
        assert values[3][2] == pytest.approx(math.remainder(yaw, math.tau), abs=1e-12)
    assert len(readings) >= 30 and abs(readings[-1][4][2]) > 0.5   # it turned: the yaw changed


def test_wall_follower_with_gps_runs_unchanged_headless(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                        clean_imports: None) -> None:  # noqa: F811
    """`from controller import Robot, GPS` in a world whose robot has a GPS, starting with a wall on its left: it
    follows the walls round the arena; its GPS log is the turret slot's position at the step's true pose."""
    script = tmp_path / 'wall_follower.py'
    script.write_text(textwrap.dedent(WALL_FOLLOWER))
    out, states = headless(script, turret_world(tmp_path, ['GPS']), 30.0, capsys)
    log = gps_lines(out)
    assert len(log) > 200
    for t, x, y, z in log[1:]:
        px, py, yaw, v, w = states[round(t * 1000)]
        assert [x, y, z] == turret.gps_values(turret.Truth.of((px, py, yaw), (v, w)))
    xs, ys = np.array([row[1] for row in log]), np.array([row[2] for row in log])
    print(f'wall follower: x {xs.min():.3f}..{xs.max():.3f}, y {ys.min():.3f}..{ys.max():.3f}')
    assert np.ptp(xs) > 0.6 and np.ptp(ys) > 0.6   # along the walls round the arena's corners (0.78, 0.9)


def test_a_script_asking_for_a_device_its_world_lacks_is_refused_in_one_line(tmp_path: Path) -> None:
    import subprocess
    import sys
    script = tmp_path / 'wall_follower.py'
    script.write_text(textwrap.dedent(WALL_FOLLOWER))
    done = subprocess.run([sys.executable, '-m', 'epuck_ros.webots_controller', str(script), '--headless',
                           '--world', str(turret_world(tmp_path, None)), '--duration', '1'],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        'webots_controller: robot "epuck" has no GPS named "gps": its world gives it none. Add one to the robot\'s '
        'turret slot in the world file, e.g. robot: {start: [0, 0, 0], turret: [GPS]} (or turret: [GPS] in its entry '
        'of robots:)']


def test_a_turret_device_named_as_an_epuck_device_is_refused_in_one_line(tmp_path: Path) -> None:
    import subprocess
    import sys
    script = tmp_path / 'wall_follower.py'
    script.write_text(textwrap.dedent(WALL_FOLLOWER))
    done = subprocess.run([sys.executable, '-m', 'epuck_ros.webots_controller', str(script), '--headless', '--world',
                           str(turret_world(tmp_path, [{'type': 'GPS', 'name': 'ps0'}])), '--duration', '1'],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        'webots_controller: the world gives robot "epuck" a turret device named "ps0", the name of one of the '
        'e-puck\'s own devices: give it another name in the world file']


def test_wall_follower_over_ros_reads_what_it_reads_headless(launch: object, test_node: object, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture,
                                                             clean_imports: None) -> None:  # noqa: F811
    """The same script through `webots_controller` and `sim` in lockstep: the GPS (from `ground_truth`, with the
    world's turret read from the latched `world` topic) logs the very numbers of the headless run."""
    script = tmp_path / 'wall_follower.py'
    script.write_text(textwrap.dedent(WALL_FOLLOWER))
    world = turret_world(tmp_path, ['GPS'])
    out, _ = headless(script, world, 6.0, capsys)
    expected = {row[0]: row for row in gps_lines(out)}
    controller = ControllerRun(launch, test_node, script, 6.0, world=world)
    controller.finish()
    assert controller.stop_controller() == 0, controller.output
    over_ros = gps_lines(controller.output)
    compared = [row for row in over_ros if row[0] in expected]
    assert len(compared) >= 80
    assert all(row == expected[row[0]] for row in compared), compared[:3]


def test_over_ros_a_device_the_world_lacks_is_refused_in_one_line(launch: object, test_node: object,
                                                                  tmp_path: Path) -> None:
    """Through `webots_controller` and a running `sim` whose world gives the robot no GPS: one line, exit 2."""
    from conftest import ros_args
    script = tmp_path / 'wall_follower.py'
    script.write_text(textwrap.dedent(WALL_FOLLOWER))
    launch('sim', *ros_args({'world': str(turret_world(tmp_path, ['Compass'])), 'real_time_factor': 0.0}))
    test_node.wait_for_simulator()
    refused = launch('webots_controller', str(script))
    assert refused.proc.wait(timeout=60.0) == 2, refused.output()
    assert refused.output().strip().splitlines()[-1] == (
        'webots_controller: robot "epuck" has no GPS named "gps": its world gives it none. Add one to the robot\'s '
        'turret slot in the world file, e.g. robot: {start: [0, 0, 0], turret: [GPS]} (or turret: [GPS] in its entry '
        'of robots:)')
