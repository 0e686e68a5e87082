"""`webots_controller`: Webots controller scripts, unchanged, against the real `sim` process over DDS.

Every run is the sim in lockstep at real_time_factor 0 (so what a controller sees does not depend on the load of
the machine), started paused and resumed once the controller is in the graph, and pausing itself at exactly
`pause_at`; the runner is a real process. Geometry is judged on `ground_truth` with the course's formulas; the
device semantics (no DDS) against Webots' reference manual.
"""
from __future__ import annotations

import importlib.util
import json
import math
import signal
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import UInt32

from conftest import ALONE_ON_THE_DOMAIN, EVERY_MESSAGE, ros_args
from epuck_ros.ir_sensor import raw_from_distance
from epuck_ros.model import FRONT_SENSORS, IR_LOOKUP_TABLE, SENSOR_POSES, RobotModel
from epuck_ros.simulation import Simulation
from epuck_ros.webots.devices import POSITION_MODE_HINT_STEPS, DistanceSensor, Motor, PositionSensor
from epuck_ros.webots.runner import EXAMPLES_DIR
from epuck_ros.world import default_world
from test_behaviour_nodes import moving, trajectory
from test_behaviours import fitted_circle

COURSE_DIR = Path(__file__).parent / 'data' / 'course_controllers'
SIM = 'sim'
TIMEOUT_PER_SIM_SECOND = 1.0
"""Wall seconds allowed per simulated second (lockstep runs here reach 5x to 10x real time)."""
MODEL = RobotModel()
FAR_RAW = float(IR_LOOKUP_TABLE[-1, 1])


# --- devices, no DDS ----------------------------------------------------------------------------------------------

def test_motor_velocity_mode_clamps_with_webots_warning_and_refuses_nan(capsys: pytest.CaptureFixture) -> None:
    motor = Motor('left wheel motor', 6.28, PositionSensor('left wheel sensor', lambda: 0))
    assert motor.getVelocity() == 6.28 and not motor.in_velocity_mode  # Webots: position control, at maxVelocity
    motor.setPosition(float('inf'))
    motor.setVelocity(10.0)
    assert "The requested velocity 10 exceeds 'maxVelocity' = 6.28." in capsys.readouterr().err
    assert motor.command(0.0) == 6.28
    motor.setVelocity(-3.0)
    assert motor.command(123.0) == -3.0
    motor.setVelocity(float('nan'))
    assert "wb_motor_set_velocity() called with an invalid 'velocity' argument" in capsys.readouterr().err
    assert motor.getVelocity() == -3.0 and motor.command(0.0) == -3.0


def test_motor_position_control_is_webots_p_controller_limited_by_velocity(capsys: pytest.CaptureFixture) -> None:
    motor = Motor('right wheel motor', 6.28, PositionSensor('right wheel sensor', lambda: 0))
    assert motor.command(1.5) == 0.0  # holds the angle it starts at
    motor.setPosition(2.0)
    motor.setVelocity(1.0)
    assert motor.command(1.5) == 1.0  # P = 10: 5 rad/s wanted, limited by the velocity
    assert motor.command(1.95) == pytest.approx(0.5)
    motor.setVelocity(-1.0)
    assert 'negative \'velocity\' argument in position control mode' in capsys.readouterr().err
    motor.setPosition(float('nan'))
    assert motor.getTargetPosition() == 2.0


def test_velocities_on_a_motor_left_in_position_control_get_one_hint(capsys: pytest.CaptureFixture) -> None:
    """Forgetting setPosition(inf) leaves the robot still, silently, in Webots: after 3 s of steps with a velocity
    set, one hint says what is missing; a motor whose position was set (position control on purpose) gets none."""
    forgot = Motor('left wheel motor', 6.28, PositionSensor('left wheel sensor', lambda: 0))
    meant = Motor('right wheel motor', 6.28, PositionSensor('right wheel sensor', lambda: 0))
    meant.setPosition(1.0)
    for motor in (forgot, meant):
        motor.setVelocity(3.0)
    for _ in range(3 * POSITION_MODE_HINT_STEPS):
        assert forgot.command(0.0) == 0.0
        meant.command(0.0)
    err = capsys.readouterr().err
    assert err.count('Hint (not from Webots): motor "left wheel motor"') == 1
    assert "call setPosition(float('inf')) once for velocity control" in err and 'right wheel motor' not in err


def test_sensors_are_nan_until_one_sampling_period_then_sample_every_period(capsys: pytest.CaptureFixture) -> None:
    now = [32_000_000]
    sensor = DistanceSensor('ps0', lambda: now[0], IR_LOOKUP_TABLE, 0.1)
    assert math.isnan(sensor.getValue())
    assert 'called for a disabled device! Please use: wb_distance_sensor_enable().' in capsys.readouterr().err
    sensor.enable(64)
    assert sensor.getSamplingPeriod() == 64
    readings = []
    for step in range(1, 6):
        now[0] = 32_000_000 * (1 + step)
        sensor.sample(now[0], 100.0 + step)
        readings.append(sensor.getValue())
    assert math.isnan(readings[0]) and readings[1:] == [102.0, 102.0, 104.0, 104.0]
    sensor.disable()
    sensor.sample(now[0] + 64_000_000, 1.0)
    assert sensor.getValue() == 104.0 and sensor.getSamplingPeriod() == 0
    assert (sensor.getMinValue(), sensor.getMaxValue()) == (FAR_RAW, 4095.0)
    encoder = PositionSensor('left wheel sensor', lambda: now[0])
    encoder.enable(32)
    encoder.sample_with_speed(now[0] + 32_000_000, 0.25, 3.14)
    assert (encoder.getValue(), encoder.getVelocity()) == (0.25, 3.14)


def test_unsupported_calls_name_what_is_supported() -> None:
    motor = Motor('left wheel motor', 6.28, PositionSensor('left wheel sensor', lambda: 0))
    with pytest.raises(AttributeError, match=r'Motor.setTorque is part of the Webots API but not supported.*'
                                             r'setVelocity'):
        motor.setTorque(1.0)


# --- processes ----------------------------------------------------------------------------------------------------

class ControllerRun:
    """`sim` (lockstep, paused until the controller is in the graph, pausing at `duration`) and the runner."""

    def __init__(self, launch: object, test_node: object, script: Path | str, duration: float, *,
                 noise: bool = False, world: Path | None = None, sim_params: dict | None = None,
                 joints: bool = False, robot: str = '') -> None:
        self.test_node = test_node
        self.duration = duration
        prefix = f'{robot}/' if robot else ''
        self.truth: list[Odometry] = test_node.collect(Odometry, prefix + 'ground_truth', EVERY_MESSAGE)
        self.joints: list[JointState] = \
            test_node.collect(JointState, prefix + 'joint_states', EVERY_MESSAGE) if joints else []
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.collisions: list[UInt32] = test_node.collect(UInt32, prefix + 'collisions', latched)
        # lockstep_timeout 3 s: a machine so loaded that the controller waits a second for the CPU does not make
        # the simulator step without its answer (a first step the controller missed is re-sent after it).
        params = {**ALONE_ON_THE_DOMAIN, 'real_time_factor': 0.0, 'lockstep': True, 'lockstep_timeout': 3.0,
                  'paused': True, 'pause_at': float(duration),
                  'noise': noise, **({'world': str(world)} if world else {}), **(sim_params or {})}
        self.sim = launch(SIM, *ros_args(params))
        test_node.wait_for_simulator()
        self.controller = launch('webots_controller', str(script), *(['--robot', robot] if robot else []))
        node = test_node.node
        # In the graph here; the sim's first step waits until it has matched the controller too (_resume), and it
        # re-sends that step until answered, so a late match costs no step.
        test_node.spin_until(lambda: node.count_publishers(prefix + 'wheel_cmd') > 0 and
                             node.count_subscribers(prefix + 'ir_raw') > 0
                             or self.controller.proc.poll() is not None, timeout=30.0, what='the controller')
        assert self.controller.proc.poll() is None, self.output
        self._resume()

    def _resume(self) -> None:
        client = AsyncParameterClient(self.test_node.node, 'sim')
        assert client.wait_for_services(20.0)
        future = client.set_parameters([Parameter('lockstep_controllers', value=1), Parameter('paused', value=False)])
        self.test_node.spin_until(future.done, what='sim to resume')

    def sim_time(self) -> float:
        stamp = self.truth[-1].header.stamp if self.truth else None
        return stamp.sec + 1e-9 * stamp.nanosec if stamp else 0.0

    def finish(self) -> np.ndarray:
        """Spin until the sim paused itself at `duration`; the ground truth as rows (t, x, y, yaw)."""
        self.test_node.spin_until(lambda: self.sim_time() >= self.duration - 1e-6,
                                  timeout=30.0 + TIMEOUT_PER_SIM_SECOND * self.duration,
                                  what=f'{self.duration} simulated s')
        return trajectory(self.truth)

    @property
    def output(self) -> str:
        """What the runner printed (stdout and stderr), also once it is stopped."""
        return self.controller.log_path.read_text()

    def stop_controller(self) -> int:
        """Ctrl-C: step() returns -1, the script's loop ends, the runner exits 0."""
        return self.controller.stop()


def example(name: str) -> Path:
    return EXAMPLES_DIR / f'{name}.py'


def test_straight_line_example_drives_at_the_course_speed(launch: object, test_node: object) -> None:
    run = ControllerRun(launch, test_node, example('straight_line'), 3.0)
    rows = moving(run.finish())[3:]
    speed = np.polyfit(rows[:, 0], rows[:, 1], 1)[0]
    print(f'straight_line: {speed:.5f} m/s, heading change {math.degrees(rows[-1, 3] - rows[0, 3]):.4f} deg')
    assert speed == pytest.approx(0.5 * 6.28 * 0.02, rel=0.005)  # 0.0628 m/s
    assert abs(rows[-1, 3] - rows[0, 3]) < 1e-6 and abs(rows[-1, 2]) < 1e-6
    assert run.stop_controller() == 0, run.output


def test_spin_example_turns_on_the_spot(launch: object, test_node: object) -> None:
    run = ControllerRun(launch, test_node, example('spin'), 3.0)
    rows = moving(run.finish())[3:]
    rate = np.polyfit(rows[:, 0], rows[:, 3], 1)[0]
    drift = float(np.hypot(*(rows[:, 1:3] - rows[0, 1:3]).T).max())
    print(f'spin: {rate:.4f} rad/s, largest drift {drift * 1000:.4f} mm')
    assert rate == pytest.approx(-0.02 / 0.052 * 6.28, rel=0.005)  # -2.415 rad/s
    assert drift < 1e-6
    # The simulator goes away: step() returns -1 and the script ends by itself, cleanly.
    assert run.sim.stop() == 0
    assert run.controller.proc.wait(timeout=20.0) == 0, run.output
    assert 'the simulator is gone' in run.output


def test_circle_example_has_the_course_radius(launch: object, test_node: object) -> None:
    run = ControllerRun(launch, test_node, example('circle'), 5.0)
    _, _, radius = fitted_circle(moving(run.finish())[3:, 1:3])
    print(f'circle: fitted radius {radius:.5f} m')
    assert radius == pytest.approx(0.026 * 0.9 / 0.3, rel=0.005)  # 0.078 m
    assert run.stop_controller() == 0, run.output


def corner_angles(rows: np.ndarray) -> np.ndarray:
    """Degrees turned in each stretch where the yaw changes."""
    turning = np.abs(np.diff(rows[:, 3])) > 1e-9
    edges = np.diff(turning.astype(int))
    starts, ends = np.flatnonzero(edges == 1) + 1, np.flatnonzero(edges == -1) + 1
    return np.degrees(rows[ends, 3] - rows[starts, 3])


def test_timed_rectangle_example_and_the_course_controller_4(launch: object, test_node: object) -> None:
    """Ours ends each phase on the nearest step, as the rectangle node: 31 steps of turning, 82.4 degrees. The
    course's program, unchanged, keeps turning while `elapsed_time < TURN_TIME`: in Webots that is 32 steps."""
    turn_rate = 0.02 / 0.052 * 0.6 * 6.28  # rad/s, R/L x (wR - wL)
    expected = {'timed_rectangle': math.degrees(31 * 0.032 * turn_rate),  # 82.4
                'controller_4': math.degrees(32 * 0.032 * turn_rate)}  # 85.0
    for script, corners in ((example('timed_rectangle'), 4), (COURSE_DIR / 'controller_4.py', 2)):
        run = ControllerRun(launch, test_node, script, 6.1 * corners + 0.5)
        angles = corner_angles(run.finish())
        assert run.stop_controller() == 0, run.output
        print(f'{script.name}: corners {np.round(angles, 3)} deg')
        assert len(angles) == corners
        assert np.allclose(angles, expected[script.stem], atol=0.01)
        run.sim.stop()


def test_avoid_example_runs_five_minutes_without_a_collision() -> None:
    """As a headless trial: the example's behaviour is the subject, not ROS (test_same_run shows the script through
    `bringup` is its headless trial to the bit; five simulated minutes over DDS took 16 s of a loaded suite)."""
    import sys
    from epuck_ros.experiments.trial import Script, Trial, run
    path_before = list(sys.path)
    try:
        _, tally = run(Trial(Script(str(example('avoid_obstacles'))), duration=300.0, noise=True))
    finally:   # the script's shim sits on sys.path while it runs
        sys.path[:] = path_before
        for module in [name for name in sys.modules if name == 'controller' or name.startswith('controller.')]:
            del sys.modules[module]
    (figures,) = tally.figures
    print(f'avoid_obstacles: {figures.world_contacts} contacts, {figures.distance:.2f} m in 300 simulated s')
    assert figures.duration == pytest.approx(300.0, abs=0.032)
    assert figures.world_contacts == 0
    assert figures.distance > 0.5 * 0.0628 * 300.0


def course_avoidance_in_the_core(seed: int, duration: float) -> np.ndarray:
    """The course's obstacle avoidance on the pure core, as Webots would step it: rows (t, x, y, yaw).

    Step 1 runs before the controller answers (wheels still); then its first step() sends the motors' state
    after setPosition(inf): Webots' initial velocity, maxVelocity; from then on each command answers the
    readings of the step just taken."""
    sim = Simulation(default_world(), seed=seed, noise=True)
    sim.step()
    left = right = MODEL.max_wheel_speed
    rows = [(sim.time, *sim.true_pose[0])]
    while True:
        sim.command_wheels(0, left, right)
        sim.step()
        rows.append((sim.time, *sim.true_pose[0]))
        if sim.time >= duration - 1e-9:
            return np.array(rows)
        values = sim.ir_raw[0]
        left = right = 0.5 * MODEL.max_wheel_speed
        if max(values[i] for i in FRONT_SENSORS) > 80.0:
            left, right = -0.4 * MODEL.max_wheel_speed, 0.4 * MODEL.max_wheel_speed
        elif values[2] > 80.0:
            left, right = 0.5 * MODEL.max_wheel_speed, 0.2 * MODEL.max_wheel_speed
        elif values[5] > 80.0:
            left, right = 0.2 * MODEL.max_wheel_speed, 0.5 * MODEL.max_wheel_speed


def test_the_course_obstacle_avoidance_runs_unchanged_step_for_step_as_on_the_core(
        launch: object, test_node: object) -> None:
    """Noise on, seed 3, lockstep: the course's program through webots_controller and the sim process gives the
    very run of the same rules stepped on the pure core: every reading was that of the step it asked for, and
    the run is as deterministic as the core is."""
    run = ControllerRun(launch, test_node, COURSE_DIR / 'obstacle_avoidance.py', 15.0, noise=True,
                        sim_params={'seed': 3})
    over_dds = run.finish()
    assert run.stop_controller() == 0, run.output
    over_dds = over_dds[np.unique(over_dds[:, 0], return_index=True)[1]]  # a first step re-sent in lockstep
    core = course_avoidance_in_the_core(3, 15.0)
    turned = float(np.abs(np.diff(core[:, 3])).sum())
    print(f'course obstacle avoidance: turned {math.degrees(turned):.1f} deg in 15 s; {len(over_dds)} steps')
    assert turned > 1.0  # it saw the walls (NaN readings would never exceed the threshold)
    assert len(over_dds) == len(core)
    assert np.allclose(over_dds[:, 0], core[:, 0], atol=1e-9, rtol=0.0)  # stamps are whole nanoseconds
    assert np.array_equal(over_dds[:, 1:3], core[:, 1:3])
    assert np.allclose(np.unwrap(core[:, 3]), over_dds[:, 3], atol=1e-12, rtol=0.0)


def expected_raw(pose: np.ndarray, face_x: float, half_width: float) -> np.ndarray:
    """Noise-free raw values of ps0..ps7 for a wall x = face_x (|y| <= half_width) in front of the robot."""
    x, y, yaw = pose
    values = []
    for sx, sy, syaw in SENSOR_POSES:
        px, py = x + sx * math.cos(yaw) - sy * math.sin(yaw), y + sx * math.sin(yaw) + sy * math.cos(yaw)
        heading = yaw + syaw
        distance = (face_x - px) / math.cos(heading) if math.cos(heading) > 1e-9 else math.inf
        if abs(py + distance * math.sin(heading)) > half_width or distance > MODEL.ir_range:
            distance = math.inf
        values.append(float(raw_from_distance(distance, IR_LOOKUP_TABLE)))
    return np.array(values)


PROBE = '''
import json
from controller import Robot

robot = Robot()
step = int(robot.getBasicTimeStep())
sensors = [robot.getDevice(f'ps{i}') for i in range(8)]
encoders = [robot.getDevice('left wheel sensor'), robot.getDevice('right wheel sensor')]
for device in sensors + encoders:
    device.enable(step)
for name in ('left wheel motor', 'right wheel motor'):
    robot.getDevice(name).setPosition(float('inf'))
    robot.getDevice(name).setVelocity(-1.0)
def show():
    print('PROBE', json.dumps({'t': robot.getTime(), 'ps': [s.getValue() for s in sensors],
                               'wheels': [e.getValue() for e in encoders]}), flush=True)
show()
while robot.step(step) != -1:
    show()
'''


def test_distance_sensors_read_the_lookup_table_of_the_step_they_asked_for(
        launch: object, test_node: object, tmp_path: Path) -> None:
    """Backing away from a wall at 0.02 m/s, noise off: every step's getValue() is the table's value for the
    distance at that very step's ground-truth pose (a reading one step late would be off by up to 60 raw)."""
    face_x, half_width = 0.045, 0.3
    world = tmp_path / 'wall.yaml'
    world.write_text(yaml.safe_dump({'arena': {'size': [1.0, 1.0]}, 'robot': {'start': [0.0, 0.0, 0.0]},
                                     'boxes': [{'position': [face_x + 0.05, 0.0], 'size': [0.1, 2 * half_width]}]}))
    script = tmp_path / 'probe.py'
    script.write_text(textwrap.dedent(PROBE))
    run = ControllerRun(launch, test_node, script, 4.0, world=world)
    rows = run.finish()
    assert run.stop_controller() == 0, run.output
    probes = [json.loads(line.split(' ', 1)[1]) for line in run.output.splitlines()
              if line.startswith('PROBE ')]
    poses = {round(t * 1000): row for t, *row in rows}
    assert all(math.isnan(v) for v in probes[0]['ps'])  # before the first sampling period: NaN
    checked = distances = 0
    for probe in probes[1:]:
        pose = np.array(poses[round(probe['t'] * 1000)])
        expected = expected_raw(pose, face_x, half_width)
        assert probe['ps'] == pytest.approx(expected, rel=1e-9, abs=1e-9), probe
        assert MODEL.wheel_radius * probe['wheels'][0] == pytest.approx(pose[0], abs=2e-4)  # encoder, radians
        checked += 1
        distances += expected[0] > FAR_RAW
    print(f'lookup table: {checked} steps checked, {distances} with ps0 seeing the wall '
          f'({probes[1]["ps"][0]:.2f} .. {FAR_RAW} raw)')
    assert checked >= 120 and distances >= 75  # ps0 sees the wall from 0.016 m to 0.07 m: 81 steps


MISUSE = '''
import importlib.util
import json
import math
from controller import Robot

robot = Robot()
again = Robot()  # Webots prints an error and goes on
step = int(robot.getBasicTimeStep())
report = {'basic_time_step': robot.getBasicTimeStep(), 'name': robot.getName(),
          'unknown_is_none': robot.getDevice('ps9') is None, 'speaker_is_none': robot.getDevice('speaker') is None,
          'typo_is_none': robot.getDevice('left wheel moter') is None}
left = robot.getMotor('left wheel motor')  # deprecated, forwards to getDevice
right = robot.getDevice('right wheel motor')
led = robot.getLED('led8')
led.set(1)
report['led'] = led.get()
report['disabled_is_nan'] = math.isnan(robot.getDevice('ps0').getValue())
try:
    robot.getKeyboard()
except AttributeError as error:
    report['keyboard'] = str(error)
try:
    from controller import Speaker
except ImportError as error:
    report['speaker_import'] = str(error)
left.setPosition(float('inf'))
right.setPosition(float('inf'))
left.setVelocity(2.0)
right.setVelocity(10.0)  # above maxVelocity: Webots warns and clamps to 6.28
left.setVelocity(float('nan'))  # refused: the motor keeps 2.0
before = robot.getTime()
robot.step(2 * step)
after_two = robot.getTime()
robot.step(step // 2)  # less than a basic step: one whole step, as Webots rounds up
report['stepped_ms'] = [round(1000 * (after_two - before)), round(1000 * (robot.getTime() - after_two))]
print('REPORT', json.dumps(report), flush=True)
while again.step(step) != -1:  # the second instance steps the one robot there is
    pass
'''


def test_misuse_gets_webots_messages_and_the_run_goes_on(launch: object, test_node: object, tmp_path: Path) -> None:
    script = tmp_path / 'misuse.py'
    script.write_text(textwrap.dedent(MISUSE))
    run = ControllerRun(launch, test_node, script, 2.0, joints=True)
    run.finish()
    assert run.stop_controller() == 0, run.output
    output = run.output
    report = json.loads(next(line for line in output.splitlines() if line.startswith('REPORT '))[7:])
    print(output)
    assert report['basic_time_step'] == 32.0 and report['name'] == 'epuck'
    assert report['unknown_is_none'] and report['speaker_is_none'] and report['disabled_is_nan']
    assert report['typo_is_none']
    assert report['led'] == 1
    assert report['stepped_ms'] == [64, 32]
    assert 'Robot.getKeyboard is part of the Webots API but not supported' in report['keyboard']
    assert 'controller.Speaker is part of the Webots API but not supported' in report['speaker_import']
    for message in ('Error: only one Robot instance can be created per controller process.',
                    'Device "ps9" was not found on robot "epuck"',
                    'Device "left wheel moter" was not found on robot "epuck" (did you mean "left wheel motor"?)',
                    'Device "speaker" exists on Webots\' e-puck but is not simulated by epuck_ros',
                    'DEPRECATION: Robot.getMotor is deprecated, please use Robot.getDevice instead.',
                    'wb_distance_sensor_get_value() called for a disabled device!',
                    'WARNING: RotationalMotor "right wheel motor": The requested velocity 10 exceeds '
                    "'maxVelocity' = 6.28.",
                    "Error: wb_motor_set_velocity() called with an invalid 'velocity' argument.(NaN)"):
        assert message in output
    assert list(run.joints[-1].velocity) == [2.0, 6.28]


HOSTILE = '''
import threading
from controller import Robot

robot = Robot()
threading.Thread(target=threading.Event().wait, name='forgotten').start()   # a non-daemon thread, never ending
print('nan:', robot.step(float('nan')), 'inf:', robot.step(float('inf')), flush=True)
done = []
def stepper():
    for _ in range(20):
        robot.step(32)
    done.append(1)
threads = [threading.Thread(target=stepper) for _ in range(3)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
print('threads stepped:', len(done), 'time:', round(robot.getTime(), 3), flush=True)
'''


def test_hostile_scripts_get_webots_messages_and_end(launch: object, test_node: object, tmp_path: Path) -> None:
    """step(nan) / step(inf) raised ValueError / OverflowError; step() from three threads raised "generator already
    executing"; a non-daemon thread left running kept the process alive after the script ended."""
    script = tmp_path / 'hostile.py'
    script.write_text(HOSTILE)
    run = ControllerRun(launch, test_node, script, 10.0)
    assert run.controller.proc.wait(timeout=60) == 0, run.output
    output = run.output
    assert 'nan: 0 inf: 0' in output and 'Traceback' not in output, output
    assert "Error: wb_robot_step() called with an invalid duration (nan)" in output
    assert "Error: wb_robot_step() called with an invalid duration (inf)" in output
    assert 'threads stepped: 3 time: 1.952' in output, output   # 60 steps after the first, one at a time


def test_a_script_that_catches_keyboard_interrupt_ends_a_second_after_sigterm(
        launch: object, test_node: object, tmp_path: Path) -> None:
    """Webots stops a controller still running one second after the simulation ends; one that caught
    KeyboardInterrupt and went on outlived it."""
    script = tmp_path / 'stubborn.py'
    script.write_text(textwrap.dedent('''
        from controller import Robot
        robot = Robot()
        while True:
            try:
                while robot.step(32) != -1:
                    pass
                print('step returned -1: going on regardless', flush=True)
                while True:
                    pass
            except KeyboardInterrupt:
                print('caught KeyboardInterrupt', flush=True)
    '''))
    run = ControllerRun(launch, test_node, script, 30.0)
    test_node.spin_until(lambda: run.sim_time() > 0.5, timeout=60, what='the script stepping')
    run.controller.proc.send_signal(signal.SIGTERM)
    assert run.controller.proc.wait(timeout=30) == 0, run.output
    assert 'going on regardless' in run.output


def test_a_script_that_stops_calling_step_is_told_so(launch: object, test_node: object, tmp_path: Path) -> None:
    """An endless loop without step() made the run creep at a step per lockstep timeout, with no word."""
    script = tmp_path / 'endless.py'
    script.write_text(textwrap.dedent('''
        from controller import Robot
        robot = Robot()
        for _ in range(5):
            robot.step(32)
        while True:
            pass
    '''))
    run = ControllerRun(launch, test_node, script, 30.0)
    test_node.spin_until(lambda: 'has not called robot.step()' in run.output, timeout=60, what='the message')
    assert run.output.count('endless.py has not called robot.step() for 5 s (at simulated t=0.192 s)') == 1
    run.controller.proc.send_signal(signal.SIGTERM)
    assert run.controller.proc.wait(timeout=30) == 0, run.output


def test_a_killed_simulator_ends_a_script_waiting_in_step_within_seconds(
        launch: object, test_node: object, tmp_path: Path) -> None:
    """SIGKILL of the simulator: step() returns -1 once the graph drops it, after the participant lease of the
    package's DDS profile (6 s); with Fast DDS's default lease that took 20.2 s."""
    import time
    script = tmp_path / 'waits.py'
    script.write_text('from controller import Robot\nrobot = Robot()\nwhile robot.step(32) != -1:\n    pass\n'
                      'print("step returned -1", flush=True)\n')
    run = ControllerRun(launch, test_node, script, 600.0, sim_params={'real_time_factor': 1.0})
    test_node.spin_until(lambda: run.sim_time() > 0.3, timeout=60, what='the script stepping')
    killed = time.monotonic()
    run.sim.proc.kill()
    assert run.controller.proc.wait(timeout=60) == 0, run.output
    took = time.monotonic() - killed
    print(f'\nstep() returned -1 {took:.1f} s after the simulator was killed')
    assert 'step returned -1' in run.output, run.output   # how soon is the lease's (a figure, not a test)


def test_a_script_that_raises_shows_its_traceback_and_the_sim_goes_on(
        launch: object, test_node: object, tmp_path: Path) -> None:
    script = tmp_path / 'raises.py'
    script.write_text(textwrap.dedent('''
        from controller import Robot

        def act():
            raise ValueError('the script failed here')

        robot = Robot()
        robot.step(int(robot.getBasicTimeStep()))
        act()
    '''))
    # The sim waits 0.05 s for answers, then steps anyway: it never pauses, so nothing here hangs on the race
    # between the controller's start and the simulator's first steps.
    run = ControllerRun(launch, test_node, script, 1000.0, sim_params={'lockstep_timeout': 0.05})
    assert run.controller.proc.wait(timeout=30.0) == 1
    output = run.output
    print(output)
    assert 'Traceback (most recent call last):' in output
    assert f'File "{script}", line 9, in <module>' in output and 'in act' in output
    assert output.rstrip().endswith('ValueError: the script failed here')
    assert 'runpy' not in output and 'runner.py' not in output
    ended_at = run.sim_time()  # the simulator goes on without the dead controller
    test_node.spin_until(lambda: run.sim_time() > ended_at + 0.5, timeout=60.0, what='simulated time to go on')
    assert run.sim.proc.poll() is None


def test_a_script_that_stops_stepping_leaves_the_robot_stopped_after_cmd_timeout(
        launch: object, test_node: object, tmp_path: Path) -> None:
    script = tmp_path / 'stalls.py'
    script.write_text(textwrap.dedent('''
        import threading
        from controller import Robot

        robot = Robot()
        for name in ('left wheel motor', 'right wheel motor'):
            robot.getDevice(name).setPosition(float('inf'))
            robot.getDevice(name).setVelocity(3.0)
        while robot.getTime() < 0.3:
            robot.step(int(robot.getBasicTimeStep()))
        print('LAST STEP', robot.getTime(), flush=True)
        threading.Event().wait()  # busy with something else, for ever
    '''))
    # lockstep_timeout 0.1 s: the sim waits for the controller while it answers, and goes on without it after.
    run = ControllerRun(launch, test_node, script, 1.3, sim_params={'lockstep_timeout': 0.1, 'cmd_timeout': 0.5})
    rows = run.finish()
    last_step = float(run.output.split('LAST STEP ')[1].split()[0])
    moving_until = rows[np.flatnonzero(np.diff(rows[:, 1]) > 0)[-1] + 1, 0]
    print(f'last step at {last_step:.3f} s, the robot moved until {moving_until:.3f} s')
    assert rows[-1, 1] > 0.01  # it drove while the script stepped
    # then cmd_timeout stopped it: 0.5 s after the last command (answering the step before the last one seen),
    # give or take the steps a loaded machine may take to answer
    assert moving_until == pytest.approx(last_step + 0.5, abs=0.1)
    assert run.stop_controller() == 0  # Ctrl-C outside step(): KeyboardInterrupt, a clean end


def test_a_finite_set_position_drives_each_wheel_to_that_angle(
        launch: object, test_node: object, tmp_path: Path) -> None:
    """Webots' default motor mode: P-control on the angle, at most at the velocity (maxVelocity by default)."""
    script = tmp_path / 'position.py'
    script.write_text(textwrap.dedent('''
        from controller import Robot

        robot = Robot()
        step = int(robot.getBasicTimeStep())
        for name in ('left wheel motor', 'right wheel motor'):
            motor = robot.getDevice(name)
            motor.getPositionSensor().enable(step)
            motor.setPosition(10.0)
        while robot.step(step) != -1:
            pass
    '''))
    run = ControllerRun(launch, test_node, script, 4.0, joints=True)
    rows = run.finish()
    assert run.stop_controller() == 0, run.output
    final = list(run.joints[-1].position)
    fastest = max(max(abs(v) for v in msg.velocity) for msg in run.joints)
    print(f'setPosition(10): wheels at {final} rad, robot at x = {rows[-1, 1]:.5f} m, fastest {fastest} rad/s')
    assert final == pytest.approx([10.0, 10.0], abs=2 * MODEL.encoder_resolution)
    assert rows[-1, 1] == pytest.approx(10.0 * MODEL.wheel_radius, abs=2 * MODEL.encoder_resolution * 0.02)
    assert fastest == pytest.approx(MODEL.max_wheel_speed)


def test_a_missing_script_gets_one_line_and_exit_2_and_help_shows_an_example(launch: object) -> None:
    missing = launch('webots_controller', '/nowhere/my_controller.py')
    assert missing.proc.wait(timeout=30.0) == 2
    assert missing.output().strip() == 'webots_controller: no such controller script: /nowhere/my_controller.py'
    helped = launch('webots_controller', '--help')
    assert helped.proc.wait(timeout=30.0) == 0
    assert 'usage: webots_controller SCRIPT.py' in helped.output() and 'avoid_obstacles.py' in helped.output()


def test_the_shim_is_not_an_installed_controller_module() -> None:
    """Only the runner puts it on sys.path: installed, it would hide a real Webots' `controller`."""
    assert importlib.util.find_spec('controller') is None


def test_robot_picks_one_robot_of_several(launch: object, test_node: object) -> None:
    """Two robots: without --robot, or with a name the world does not have, one line and exit 2; --robot epuck1
    drives epuck1 (its topics under epuck1/) and epuck0, which nobody drives, stays where it is."""
    others = test_node.collect(Odometry, 'epuck0/ground_truth', EVERY_MESSAGE)
    run = ControllerRun(launch, test_node, example('spin'), 3.0, robot='epuck1', sim_params={'robots': 2})
    rows = run.finish()
    assert run.stop_controller() == 0, run.output
    rate = np.polyfit(*moving(rows)[3:, [0, 3]].T, 1)[0]
    still = trajectory(others)
    print(f'--robot epuck1: {rate:.4f} rad/s; epuck0 moved {np.ptp(still[:, 1:], axis=0)}')
    assert rate == pytest.approx(-2.415, rel=0.005)
    assert np.ptp(still[:, 1:], axis=0).max() == 0.0
    wrong = {'the simulator has several robots (epuck0, epuck1): choose one with --robot NAME':
             launch('webots_controller', str(example('spin'))),
             '--robot epuck7: no such robot in the simulator (robots: epuck0, epuck1)':
             launch('webots_controller', str(example('spin')), '--robot', 'epuck7')}
    for line, process in wrong.items():
        assert process.proc.wait(timeout=30.0) == 2
        assert process.output().strip().splitlines()[-1] == f'webots_controller: {line}'
        assert 'Traceback' not in process.output()
