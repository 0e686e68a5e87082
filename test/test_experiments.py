"""Headless trials and sweeps: the same runs as over ROS to the bit, on a real Dask cluster, resumable, and bad
specs refused before any trial."""
from __future__ import annotations

import csv
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import BIN_DIR, EVERY_MESSAGE

from epuck_ros.bag.reader import Bag
from epuck_ros.bag.run_summary import load_runs
from epuck_ros.behaviours import Observation, WheelCommand
from epuck_ros.experiments.cluster import SCHEDULER_TIMEOUT
from epuck_ros.experiments.trial import Script, Trial, controller_from, run, run_trial
from epuck_ros.model import MAX_WHEEL_SPEED, TIME_STEP, RobotModel

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / 'epuck_ros' / 'experiments' / 'examples' / 'avoid_seeds.yaml'
SWEEP = str(BIN_DIR / 'sweep')
COURSE_AVOIDANCE = REPO / 'test' / 'data' / 'course_controllers' / 'obstacle_avoidance.py'
STEP_TOPICS = ('/clock', '/ground_truth', '/odom', '/ir_raw', '/joint_states', '/proximity', '/collisions')


def headless_poses(trial: Trial) -> tuple[np.ndarray, object]:
    """Every step's true poses (steps, robots, 3) of a headless trial run in this process, and its result. A
    script's shim sits on sys.path while it runs, as for a library user: taken off again here."""
    poses: list[np.ndarray] = []
    path_before = list(sys.path)
    try:
        result, _ = run(trial, each_step=lambda sim: poses.append(sim.true_pose.copy()))
    finally:
        sys.path[:] = path_before
        for module in [name for name in sys.modules if name == 'controller' or name.startswith('controller.')]:
            del sys.modules[module]
    return np.array(poses), result


@pytest.mark.parametrize('controller, robots', [('avoid', 0), ('avoid', 3), ('script', 3)])
def test_a_headless_trial_is_the_lockstep_bringup_run_to_the_bit(launch, tmp_path, controller, robots):
    """Every ground-truth pose of a recorded `bringup avoid --lockstep --real-time-factor 0` run (or `bringup
    --controller` with the course's obstacle_avoidance.py, one webots_controller per robot) equals the headless
    trial's, bit for bit (noise on, obstacles met)."""
    bag = tmp_path / 'ros'
    chosen = ['avoid'] if controller == 'avoid' else ['--controller', str(COURSE_AVOIDANCE)]
    run_ros = launch('bringup', *chosen, '--duration', '12', '--real-time-factor', '0', '--seed', '3', '--lockstep',
                     *(['--robots', str(robots)] if robots else []), '--record', str(bag))
    assert run_ros.proc.wait(timeout=180) == 0, run_ros.output()
    trial_controller = controller_from('avoid') if controller == 'avoid' else Script(str(COURSE_AVOIDANCE))
    headless, _ = headless_poses(Trial(trial_controller, robots=robots, seed=3, duration=12))
    with Bag(bag) as reader:
        runs = load_runs(reader)
    assert len(runs) == max(robots, 1)
    for index, recorded in enumerate(runs):
        truth = recorded.truth
        assert len(truth.x) == len(headless), recorded.name
        assert np.array_equal(truth.x, headless[:, index, 0]) and np.array_equal(truth.y, headless[:, index, 1]), \
            f'{recorded.name}: first difference at step {np.flatnonzero(truth.x != headless[:, index, 0])[:1]}'


def messages_by_topic(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of a bag as rosbags' AnyReader reads (and deserialises) it: topic -> [(log time, CDR)]."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    found: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection, stamp, data in reader.messages():
            reader.deserialize(data, connection.msgtype)
            found.setdefault(connection.topic, []).append((stamp, bytes(data)))
    return found


def test_a_headless_script_is_the_lockstep_bringup_run_and_records_the_same_bag(launch, tmp_path):
    """The course's obstacle_avoidance.py, unchanged, through `bringup --controller` in lockstep (simulator and
    webots_controller over DDS) and through `webots_controller --headless --record`: the same summary, and every
    step message of the two bags the same bytes, stamps included (ground truth, odometry, IR, joints, contacts),
    read back by rosbags."""
    common = ['--seed', '3', '--duration', '15']
    ros_bag, headless_bag = tmp_path / 'ros', tmp_path / 'headless'
    over_ros = launch('bringup', '--controller', str(COURSE_AVOIDANCE), '--lockstep', '--real-time-factor', '0',
                      *common, '--record', str(ros_bag))
    headless = subprocess.run([str(BIN_DIR / 'webots_controller'), str(COURSE_AVOIDANCE), '--headless', *common,
                               '--record', str(headless_bag)], capture_output=True, text=True, timeout=120)
    assert headless.returncode == 0, headless.stderr
    assert over_ros.proc.wait(timeout=180) == 0, over_ros.output()
    figures = [line.split('] ', 1)[1] for line in headless.stdout.splitlines()[1:] if 'recorded to' not in line]
    assert ' with walls/obstacles; final pose x ' in figures[0]
    assert all(f'[bringup] {line}' in over_ros.output() for line in figures), (figures, over_ros.output())
    ros, mine = messages_by_topic(ros_bag), messages_by_topic(headless_bag)
    assert len(mine['/ground_truth']) == round(15.008 / 0.032)
    for topic in STEP_TOPICS:   # the recorder's log times are its clock's when a message came: not compared
        assert [data for _, data in mine[topic]] == [data for _, data in ros[topic]], topic
    with Bag(headless_bag) as reader:
        (recorded,) = load_runs(reader)
    assert recorded.truth.x[-1] != recorded.truth.x[0]


def test_a_failing_controller_is_a_row_per_robot_with_its_error_and_the_trials_own_values():
    def broken(observation):
        raise RuntimeError('controller bug')
    (row,) = run_trial(Trial(controller_from('avoid'), duration=1), policy=broken)
    assert row['error'] == 'RuntimeError: controller bug' and (row['robot'], row['robots']) == ('epuck', 1)
    rows = run_trial(Trial(controller_from('avoid'), robots=3, seed=4, duration=1, index=7), policy=broken)
    assert [(row['trial'], row['robots'], row['seed'], row['robot'], row['error']) for row in rows] == \
        [(7, 3, 4, f'epuck{i}', 'RuntimeError: controller bug') for i in range(3)]


def test_a_policy_of_the_forward_behaviours_speeds_is_the_forward_trial():
    """A plain Python policy gets an observation per robot and step and drives as the behaviour it imitates: the
    same rows (a robot that met a wall too), and speed x time for a robot that met nothing."""
    observed: list[Observation] = []

    def half_speed(observation: Observation) -> WheelCommand:
        observed.append(observation)
        return WheelCommand.fractions(0.5, 0.5)   # what `forward` with its defaults commands
    trial = Trial(controller_from('forward'), robots=3, seed=0, duration=3.0)
    with_policy = run_trial(trial, policy=half_speed)
    without_wall = [{key: value for key, value in row.items() if key != 'wall_s'} for row in with_policy]
    assert without_wall == [{key: value for key, value in row.items() if key != 'wall_s'} for row in run_trial(trial)]
    assert all(row['error'] == '' for row in with_policy) and {row['contacts_obstacles'] for row in with_policy} == \
        {0, 1}   # seed 0 puts one robot before a wall
    steps = round(with_policy[0]['sim_time'] / TIME_STEP)   # the first step goes out with the wheels still
    for row in with_policy:
        if row['contacts_obstacles'] == 0:
            assert row['distance_m'] == pytest.approx(0.5 * MAX_WHEEL_SPEED * RobotModel().wheel_radius *
                                                      TIME_STEP * (steps - 1), rel=1e-9)
    assert len(observed) == 3 * (steps - 1) and all(len(seen.ranges) == 8 for seen in observed)
    assert [seen.time for seen in observed[::3]] == pytest.approx([TIME_STEP * (k + 1) for k in range(steps - 1)])


def rows_of(table: Path) -> list[dict]:
    """The rows without their wall time (the only column that depends on the machine)."""
    with open(table, newline='') as stream:
        return [{key: value for key, value in row.items() if key != 'wall_s'} for row in csv.DictReader(stream)]


def sweep(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([SWEEP, *args], capture_output=True, text=True, timeout=timeout)


def small_spec(tmp_path: Path, count: int = 6, duration: float = 10, robots: str = '[1, 3]') -> Path:
    spec = tmp_path / 'spec.yaml'
    spec.write_text(f'controllers: [avoid, {{behaviour: avoid, parameters: {{cruise_speed: 0.7}}}}]\n'
                    f'robots: {robots}\nseeds: {{first: 0, count: {count}}}\nduration: {duration}\n')
    return spec


def test_in_process_and_on_a_local_cluster_give_the_same_rows(tmp_path):
    spec = small_spec(tmp_path, count=3, duration=5)
    alone, local = sweep(str(spec), '-o', str(tmp_path / 'alone'), '--workers', '0'), \
        sweep(str(spec), '-o', str(tmp_path / 'local'), '--workers', '2')
    assert alone.returncode == 0 and local.returncode == 0, alone.stderr + local.stderr
    rows = rows_of(tmp_path / 'alone' / 'trials.csv')
    assert len(rows) == 2 * 3 * (1 + 3) and rows == rows_of(tmp_path / 'local' / 'trials.csv')
    assert 'on a local Dask cluster of 2 workers' in local.stderr and '12/12 trials, 0 failed' in local.stderr
    assert (tmp_path / 'local' / 'sweep.png').stat().st_size > 10_000
    assert 'avoid cruise_speed=0.7' in alone.stdout and '±' in alone.stdout
    first = rows[0]
    assert float(first['final_x']) == float(repr(float(first['final_x']))) and first['error'] == ''


def _cores_of_every_thread() -> list[int]:
    return sorted({core for thread in os.listdir('/proc/self/task') for core in os.sched_getaffinity(int(thread))})


@pytest.mark.skipif(not hasattr(os, 'sched_setaffinity'), reason='thread placement is Linux only')
def test_a_local_cluster_keeps_each_worker_on_a_core_of_its_own():
    """Else a trial's GIL releases wake the worker's event loop on another core, and the trial pays for it
    (experiments/placement.py)."""
    from epuck_ros.experiments.cluster import open_client
    cores = sorted(os.sched_getaffinity(0))
    with open_client(2, None) as client:
        placed = client.run(_cores_of_every_thread)
        names = client.run(lambda dask_worker: dask_worker.name)
    by_name = {names[address]: cores_of_worker for address, cores_of_worker in placed.items()}
    assert by_name == {0: [cores[0]], 1: [cores[1 % len(cores)]]}


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def wait_for_workers(address: str, count: int) -> None:
    """Until the scheduler at `address` answers and `count` workers have joined it (a loaded machine may take
    longer to start them than the sweep gives a scheduler to answer)."""
    from dask.distributed import Client
    deadline = time.monotonic() + 120
    while True:
        try:
            with Client(address, timeout=5) as client:
                client.wait_for_workers(count, timeout=max(1.0, deadline - time.monotonic()))
                return
        except (OSError, TimeoutError):
            if time.monotonic() > deadline:
                raise


def test_a_real_cluster_with_a_worker_killed_mid_sweep_runs_every_trial_once(tmp_path):
    """`dask scheduler` and two `dask worker` processes on loopback; one worker is SIGKILLed once a third of the
    trials are written: Dask re-runs its trials elsewhere and the rows equal an in-process run's."""
    spec = small_spec(tmp_path, count=12, duration=120, robots='[1]')
    port = free_port()
    address = f'tcp://127.0.0.1:{port}'
    dask = str(BIN_DIR / 'dask')
    env = dict(os.environ, PYTHONPATH=str(REPO))
    started = [subprocess.Popen([dask, 'scheduler', '--host', '127.0.0.1', '--port', str(port),
                                 '--dashboard-address', ':0'], env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        for _ in range(2):
            started.append(subprocess.Popen([dask, 'worker', address, '--nthreads', '1', '--no-dashboard',
                                             '--host', '127.0.0.1'], env=env, stdout=subprocess.DEVNULL,
                                            stderr=subprocess.DEVNULL, start_new_session=True))
        wait_for_workers(address, 2)
        out = tmp_path / 'cluster'
        run_sweep = subprocess.Popen([SWEEP, str(spec), '-o', str(out), '--scheduler', address],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        table = out / 'trials.csv'
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and run_sweep.poll() is None and \
                (not table.exists() or len(table.read_text().splitlines()) < 1 + 8):
            time.sleep(0.05)
        written = len(table.read_text().splitlines()) - 1 if table.exists() else 0
        assert run_sweep.poll() is None and written < 24, 'the sweep ended before a worker could be killed'
        victim = started[1]
        victim.kill()
        victim.wait(timeout=30)
        stdout, stderr = run_sweep.communicate(timeout=300)
        assert run_sweep.returncode == 0, stderr
        alone = sweep(str(spec), '-o', str(tmp_path / 'alone'), '--workers', '0')
        assert alone.returncode == 0, alone.stderr
        rows = rows_of(table)
        assert [int(row['trial']) for row in rows] == list(range(24))
        assert rows == rows_of(tmp_path / 'alone' / 'trials.csv')
    finally:
        for process in started:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in started:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


def test_resume_runs_only_the_trials_not_written_yet(tmp_path):
    spec = small_spec(tmp_path, count=4, duration=5, robots='[1]')
    out = tmp_path / 'out'
    assert sweep(str(spec), '-o', str(out), '--workers', '0').returncode == 0
    whole = rows_of(out / 'trials.csv')
    lines = (out / 'trials.csv').read_text().splitlines(keepends=True)
    (out / 'trials.csv').write_text(''.join(lines[:4]) + lines[4][:20])   # 3 trials, then a line cut short
    resumed = sweep(str(spec), '-o', str(out), '--workers', '0', '--resume')
    assert resumed.returncode == 0, resumed.stderr
    assert '8 trials (3 done before)' in resumed.stderr and '5/5 trials' in resumed.stderr
    assert rows_of(out / 'trials.csv') == whole


@pytest.mark.parametrize('text, message', [
    ('controllers: [avoidd]\nseeds: [0]\nduration: 5\n',
     "controllers[0]: unknown behaviour 'avoidd' (did you mean avoid?)"),
    ('controllers: [{behaviour: avoid, parameters: {cruise_sped: 1}}]\nseeds: [0]\nduration: 5\n',
     'controllers[0].parameters.cruise_sped: avoid has no such setting (did you mean cruise_speed?)'),
    ('controllers: [avoid]\nworlds: [missing.yaml]\nseeds: [0]\nduration: 5\n', 'worlds[0]: '),
    ('controllers: [avoid]\nseeds: [0]\nduration: 0\n', 'duration: expected simulated seconds above 0'),
    ('controllers: [avoid]\nseeds: [0]\nduration: 1e9\n', 'duration: expected simulated seconds above 0'),
    ('controllers: [avoid]\nseeds: {first: 0, count: 100000}\nrobots: [1, 2]\nduration: 5\n',
     '200000 trials, more than 100000'),
    ('controllers: [avoid]\nseeds: [0]\nduration: 5\nnoisy: true\n', 'noisy: unknown key (did you mean noise?)'),
    ('controllers: [{script: my_controller.py}]\nseeds: [0]\nduration: 5\n',
     'controllers[0].script: my_controller.py: file not found'),
    ('controllers: [avoid, {script: broken.py}]\nseeds: [0]\nduration: 5\n',
     'controllers[1].script: broken.py is not valid Python: '),
    ('controllers: [{script: broken.py, args: 1}]\nseeds: [0]\nduration: 5\n', 'controllers[0].args: unknown key'),
    ('controllers: [{behaviour: avoid, parameter: {}}]\nseeds: [0]\nduration: 5\n',
     'controllers[0].parameter: unknown key'),
    ('controllers: [avoid]\nseeds: [0]\nduration: 5\ntime_limit: 0\n', 'time_limit: expected wall seconds above 0'),
    ('controllers: [avoid]\nseeds: [0]\nduration: -1\n', 'duration: expected simulated seconds above 0'),
    ('controllers: [avoid]\nseeds: [0]\nrobots: [500]\nduration: 5\n', 'robots: 500 in default: '),
    ('controllers: [avoid]\nduration: 5\n', 'seeds: missing'),
])
def test_a_bad_spec_is_one_line_and_exit_2_before_any_trial(tmp_path, text, message):
    spec = tmp_path / 'bad.yaml'
    spec.write_text(text)
    (tmp_path / 'broken.py').write_text('from controller import Robot\nwhile True\n')
    result = sweep(str(spec), '-o', str(tmp_path / 'out'), '--workers', '0', timeout=60)
    assert result.returncode == 2 and message in result.stderr, result.stderr
    assert result.stderr.count('\n') == 1 and str(spec) in result.stderr
    assert not (tmp_path / 'out' / 'trials.csv').exists()


class SilentListener:
    """A TCP port that accepts connections and never says a word: no Dask scheduler, yet reachable."""

    def __init__(self) -> None:
        self.server = socket.create_server(('127.0.0.1', 0))
        self.address = f'tcp://127.0.0.1:{self.server.getsockname()[1]}'
        self.accepted: list[socket.socket] = []
        self.thread = threading.Thread(target=self._accept, daemon=True)
        self.thread.start()

    def _accept(self) -> None:
        while True:
            try:
                self.accepted.append(self.server.accept()[0])
            except OSError:   # closed
                return

    def close(self) -> None:
        self.server.shutdown(socket.SHUT_RDWR)
        self.server.close()
        self.thread.join(timeout=10)
        for connection in self.accepted:
            connection.close()


def test_an_unreachable_scheduler_is_one_line_and_exit_2(tmp_path):
    """Nothing listens on the port: said at once; a port that accepts but never answers as a scheduler: said once the
    sweep's limit for the whole connection (SCHEDULER_TIMEOUT) has passed, which the line names, not a hang (the run's
    own time-out would fail the test). How long each took is printed, not asserted: a loaded machine starts the
    process slowly."""
    listener = SilentListener()
    try:
        for address in (f'tcp://127.0.0.1:{free_port()}', listener.address):
            began = time.monotonic()
            result = sweep(str(small_spec(tmp_path, count=1, duration=1)), '-o', str(tmp_path / 'out'),
                           '--scheduler', address, timeout=120)
            took = time.monotonic() - began
            assert result.returncode == 2 and 'cannot reach the Dask scheduler' in result.stderr, result.stderr
            assert result.stderr.count('\n') == 1 and 'Traceback' not in result.stderr, result.stderr
            if address == listener.address:   # gave up at the limit the line names
                assert f'within {SCHEDULER_TIMEOUT:g} s' in result.stderr, result.stderr
            print(f'\n{address}: unreachable scheduler reported after {took:.1f} s')
    finally:
        listener.close()


def test_sweep_help_names_the_options():
    result = subprocess.run([SWEEP, '--help'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and all(option in result.stdout for option in ('--workers', '--scheduler',
                                                                                 '--resume', '-o'))


def test_the_example_spec_loads():
    from epuck_ros.experiments.spec import load_spec
    assert len(load_spec(EXAMPLE).trials) == 3 * 2 * 4
    assert sys.executable


MISBEHAVING = {
    'raises.py': 'from controller import Robot\nrobot = Robot()\nrobot.step(32)\n1 / 0\n',
    'exits.py': 'import sys\nfrom controller import Robot\nrobot = Robot()\nrobot.step(32)\nsys.exit(3)\n',
    'dies.py': 'import os\nfrom controller import Robot\nrobot = Robot()\nrobot.step(32)\nos._exit(5)\n',
    'loops.py': 'from controller import Robot\nrobot = Robot()\nwhile True:\n    pass\n',
    'chatters.py': 'import os\nfrom controller import Robot\nrobot = Robot()\nwhile robot.step(32) != -1:\n'
                   '    print("x" * 1_000_000)\n    os.write(1, b"y" * 1_000_000)\n',
}


def test_script_trials_that_misbehave_are_rows_saying_what_happened_and_the_sweep_goes_on(tmp_path):
    """Each in a forked child of the sweep: a script that raises, calls sys.exit(3) or os._exit(5), loops without
    step() (a sweep of its own, with a time limit of 3 s: no other trial's wall time depends on the machine's
    load), or prints 2 MB per step is one row with its error each; the course's controller beside them runs, gives
    the rows of the same trial in this process, and its bag (--record) is read by rosbags."""
    for name, text in MISBEHAVING.items():
        (tmp_path / name).write_text(text)
    shutil.copy(COURSE_AVOIDANCE, tmp_path / 'course.py')
    spec, looping = tmp_path / 'scripts.yaml', tmp_path / 'loops.yaml'
    spec.write_text('controllers: [' + ', '.join(f'{{script: {name}}}' for name in [*MISBEHAVING, 'course.py']
                                                 if name != 'loops.py') + ']\nseeds: [1]\nduration: 3\n')
    looping.write_text('controllers: [{script: loops.py}]\nseeds: [1]\nduration: 3\ntime_limit: 3\n')
    out = tmp_path / 'out'
    result = sweep(str(spec), '-o', str(out), '--workers', '0', '--record', timeout=240)
    assert result.returncode == 1, result.stderr
    rows = {row['controller']: row for row in rows_of(out / 'trials.csv')}
    assert sweep(str(looping), '-o', str(tmp_path / 'loops'), '--workers', '0').returncode == 1
    rows.update({row['controller']: row for row in rows_of(tmp_path / 'loops' / 'trials.csv')})
    assert rows['raises.py']['error'] == \
        'ScriptError: raises.py: ZeroDivisionError: division by zero (line 4 of raises.py)'
    assert rows['exits.py']['error'] == 'ScriptError: exits.py: sys.exit(3)'
    assert rows['dies.py']['error'] == "the trial's process ended (exit code 5) before its result"
    assert rows['loops.py']['error'] == \
        "no result within 3 wall seconds (the time limit): the trial's process was killed"
    assert rows['chatters.py']['error'] == '' and rows['course.py']['error'] == ''
    from epuck_ros.experiments.spec import load_spec
    course = next(trial for trial in load_spec(spec).trials if trial.controller.label == 'course.py')
    (alone,) = run_trial(course)
    assert {key: str(value) for key, value in alone.items() if key != 'wall_s'} == \
        {key: value for key, value in rows['course.py'].items()}
    bag = out / 'bags' / rows['course.py']['trial']
    truth = messages_by_topic(bag)['/ground_truth']
    assert len(truth) == round(3.008 / 0.032) and truth[-1][0] == round(float(rows['course.py']['sim_time']) * 1e9)


def stamp_ns(msg: object) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def test_three_robots_each_driven_by_a_script_over_dds_are_the_headless_trial(launch, test_node):
    """`sim` with 3 robots in lockstep and one `webots_controller --robot NAME` process per robot, all running the
    course's obstacle_avoidance.py: every robot's ground truth and contact count equal the headless 3-robot
    script trial's (a thread per robot in one process), to the bit. lockstep_timeout 10 s: on a loaded machine a
    step the sim passed because the three controllers waited seconds for the CPU would make the runs differ."""
    from nav_msgs.msg import Odometry
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import UInt32
    names = [f'epuck{i}' for i in range(3)]
    truth = {name: test_node.collect(Odometry, f'{name}/ground_truth', EVERY_MESSAGE) for name in names}
    contacts = {name: test_node.collect(UInt32, f'{name}/collisions', QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)) for name in names}
    sim = launch('sim', '--ros-args', '-p', 'robots:=3', '-p', 'seed:=3', '-p', 'lockstep:=true', '-p',
                 'lockstep_timeout:=10.0', '-p', 'real_time_factor:=0.0', '-p', 'paused:=true', '-p', 'pause_at:=8.0')
    test_node.wait_for_simulator()
    controllers = [launch('webots_controller', str(COURSE_AVOIDANCE), '--robot', name) for name in names]
    node = test_node.node
    test_node.spin_until(lambda: all(node.count_publishers(f'{name}/wheel_cmd') > 0 and
                                     node.count_subscribers(f'{name}/ir_raw') > 0 for name in names),
                         timeout=60.0, what='three controllers')
    client = AsyncParameterClient(node, 'sim')
    assert client.wait_for_services(20.0)
    # The simulator's first step waits until it has matched the three controllers this node sees.
    test_node.spin_until(client.set_parameters([Parameter('lockstep_controllers', value=3),
                                                Parameter('paused', value=False)]).done, what='the resume')
    last = 8_000_000_000   # ns: the simulator pauses itself there
    test_node.spin_until(lambda: all(received and stamp_ns(received[-1]) >= last for received in truth.values()),
                         timeout=120.0, what='8 simulated s')
    poses, headless = headless_poses(Trial(Script(str(COURSE_AVOIDANCE)), robots=3, seed=3, duration=8.0))
    assert list(headless.names) == names
    for index, name in enumerate(names):
        steps = {stamp_ns(msg): (msg.pose.pose.position.x, msg.pose.pose.position.y) for msg in truth[name]}
        over_dds = np.array([steps[stamp] for stamp in sorted(steps)])   # a first step re-sent in lockstep: once
        assert np.array_equal(over_dds, poses[:, index, :2]), f'{name}\n{sim.output()[-4000:]}'
        assert contacts[name][-1].data == int(headless.collisions[index]), name
    assert sum(int(count) for count in headless.collisions) > 0   # they met walls or each other: not a trivial run
    for controller in controllers:
        assert controller.stop() == 0, controller.output()
