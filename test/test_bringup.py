"""The entry script: starts sim + controller (+ recorder, view) as processes and always stops them all.

Runs use lockstep (bringup's default), so what they do does not depend on the machine's load; waits are on
conditions (output lines, the graph, processes gone) with generous timeouts, never on elapsed time."""
from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import textwrap
import time
import urllib.request
from pathlib import Path

import pytest
from conftest import BIN_DIR, processes_in_this_domain, set_sim_parameter

from epuck_ros.bringup.cli import parse_args

SIMULATED = re.compile(r'\[bringup\] simulated ([\d.]+) s in [\d.]+ s wall \(([\d.]+)x real time\)')
ROBOT = re.compile(r'\[bringup\] (?:(\w+): )?([\d.]+) m in [\d.]+ s, (\d+) contacts? with walls/obstacles')


def summary_of(output: str) -> tuple[float, float, int]:
    """(simulated s, distance m, contacts) from bringup's summary of a one-robot run."""
    simulated, robots = SIMULATED.search(output), ROBOT.findall(output)
    assert simulated and len(robots) == 1, output
    return float(simulated[1]), float(robots[0][1]), int(robots[0][2])


def rclpy_script(path: Path, body: str) -> Path:
    """An rclpy controller script: `body` (indented as in a test, makes `node`) between rclpy.init() and the Jazzy
    spin with try / except / finally."""
    path.write_text('import rclpy\nfrom rclpy.executors import ExternalShutdownException\n\nrclpy.init()\n'
                    + textwrap.dedent(body) + textwrap.dedent('''
        try:
            rclpy.spin(node)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            rclpy.try_shutdown()
    '''))
    return path


def child_pids() -> list[int]:
    """The ROS processes of this test's domain other than bringup itself."""
    return [pid for pid, cmd in processes_in_this_domain() if '/bringup' not in cmd]


def wait_until_gone(pids: list[int], timeout: float) -> list[int]:
    """Wait (bounded) until none of `pids` is a live process; returns those still alive."""
    deadline = time.monotonic() + timeout
    while True:
        alive = [pid for pid in pids if _alive(pid)]
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.1)


def _alive(pid: int) -> bool:
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != 'Z'


def test_the_domain_is_watched_longer_on_a_machine_loaded_beyond_its_cores(monkeypatch):
    """A second bringup beside four test processes and a busy loop per core heard the first run's simulator only
    after starting its children: the window before anything starts stretches with the load per core."""
    from epuck_ros.bringup import run as bringup_run, tables
    window = float(tables.sim_default('discovery_window'))
    monkeypatch.setattr(os, 'cpu_count', lambda: 2)
    for load, stretch in ((0.5, 1.0), (2.0, 1.0), (5.0, 2.5), (40.0, bringup_run.LOAD_STRETCH)):
        monkeypatch.setattr(os, 'getloadavg', lambda: (load, load, load))
        assert bringup_run.discovery_window() == pytest.approx(window * stretch), load


def test_parameters_go_to_the_node_that_declares_them_as_their_type():
    args, plan = parse_args(['rectangle', '--seed', '7', '--no-noise', '-p', 'turn_mode:=timed',
                             '-p', 'cmd_timeout:=2', '-p', 'rectangle.side_a:=0.2', '-p', 'sim.real_time_factor:=0'])
    assert plan.controller_params == ['turn_mode:=timed', 'side_a:=0.2']
    # Integers given for float parameters reach the node as floats: `-p cruise_speed:=1` works.
    assert {'seed:=7', 'noise:=false', 'cmd_timeout:=2.0', 'real_time_factor:=0.0', 'lockstep:=true',
            'paused:=true'} <= set(plan.sim_params)
    # bringup looks for another simulator itself before the resume: the sim steps as soon as it is resumed.
    assert 'discovery_window:=0.0' in plan.sim_params
    _, plan = parse_args(['avoid', '-p', 'cruise_speed:=1'])
    assert plan.controller_params == ['cruise_speed:=1.0']
    _, plan = parse_args(['avoid', '--no-lockstep'])
    assert 'lockstep:=false' in plan.sim_params


def test_several_robots_are_driven_by_one_behaviour_process():
    _, plan = parse_args(['avoid', '--robots', '20'])
    assert 'robots:=20' in plan.sim_params
    assert plan.controller_command == ['avoid', '--robots', 'all']
    _, plan = parse_args(['avoid'])
    assert plan.controller_command == ['avoid']


def test_a_controller_script_runs_as_webots_or_as_rclpy(tmp_path):
    webots = tmp_path / 'webots_style.py'
    webots.write_text('from controller import Robot\nrobot = Robot()\n')
    own = tmp_path / 'own_node.py'
    own.write_text('import rclpy\n')
    _, plan = parse_args(['--controller', str(webots), '--robot', 'epuck'])
    assert plan.controller_kind == 'webots'
    assert plan.controller_command == ['webots_controller', str(webots.resolve()), '--robot', 'epuck']
    _, plan = parse_args(['--controller', str(own)])
    assert plan.controller_kind == 'rclpy'
    assert plan.controller_command == [sys.executable, str(own.resolve())]


def test_a_webots_script_on_several_robots_runs_once_per_robot(tmp_path):
    """As Webots runs a controller on each robot (and a headless trial one copy per robot); --robot picks one."""
    script = tmp_path / 'webots_style.py'
    script.write_text('from controller import Robot\nrobot = Robot()\n')
    _, plan = parse_args(['--controller', str(script), '--robots', '3'])
    assert (plan.script_robots, plan.robots_to_drive) == (('epuck0', 'epuck1', 'epuck2'), 'all')
    world = tmp_path / 'two.yaml'
    world.write_text('robots:\n  - {name: alpha, start: [0.2, 0, 0]}\n  - {name: beta, start: [-0.2, 0, 0]}\n')
    _, plan = parse_args(['--controller', str(script), '--world', str(world)])
    assert plan.script_robots == ('alpha', 'beta')
    _, plan = parse_args(['--controller', str(script), '--world', str(world), '--robot', 'beta'])
    assert (plan.script_robots, plan.robots_to_drive) == ((), ('beta',))


@pytest.mark.parametrize('argv, message', [
    (['dance'], 'invalid choice'),
    (['avoid', '--duration', '-3'], '--duration'),
    (['avoid', '-p', 'oops'], 'NAME:=VALUE'),
    (['avoid', '-p', 'cruise_speed:='], 'empty value'),
    (['avoid', '-p', 'turtle.speed:=1'], 'unknown node'),
    (['avoid', '--world', '/no/such.yaml'], 'no such file'),
    (['forward', '-p', 'goal_distnace:=0.3'], 'did you mean goal_distance?'),
    (['forward', '-p', 'sim.seeed:=3'], 'did you mean seed?'),
    (['forward', '-p', 'sim.seed:=abc'], "seed: expected an integer, got abc"),
    (['avoid', '-p', 'cruise_speed:=99'], 'cruise_speed: 99'),
    (['avoid', '--namespace', 'bad ns!'], "--namespace 'bad ns!'"),
    (['--controller', '/no/such_controller.py'], 'no such file'),
    (['avoid', '--controller', __file__], 'not both'),
    (['avoid', '--robots', '0'], '--robots'),
])
def test_bad_arguments_are_refused_with_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        parse_args(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert message in err
    assert len(err.strip().splitlines()) == 1, err


def test_a_refused_command_line_starts_nothing_and_prints_no_traceback():
    result = subprocess.run([str(BIN_DIR / 'bringup'), 'forward', '-p', 'name:=', '--namespace', 'bad ns!'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert 'Traceback' not in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert processes_in_this_domain() == []


def test_a_run_with_duration_ends_by_itself_and_leaves_no_process(launch, test_node):
    run = launch('bringup', 'forward', '--duration', '4', '--real-time-factor', '0', '--no-noise')
    assert run.proc.wait(timeout=90) == 0, run.output()
    simulated, distance, collisions = summary_of(run.output())
    assert simulated == pytest.approx(4.0, abs=0.032)
    # In lockstep the robot drives at 0.0628 m/s from the first step (t = 0.032 s) to the last.
    assert distance == pytest.approx(0.0628 * (simulated - 0.032), abs=2e-3)
    assert collisions == 0
    # The pace once stepping is printed apart from the pace since the resume (which holds the sim's start-up).
    stepping = re.search(r'([\d.]+)x real time from the first step, which came ([\d.]+) s after the resume',
                         run.output())
    assert stepping and float(stepping[1]) > 0.0, run.output()
    assert f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}' in run.output()
    assert processes_in_this_domain() == []


def wait_until_running(test_node) -> None:
    """Wait until the run is under way, from its messages: the simulator was resumed and ticks `/clock`."""
    from rosgraph_msgs.msg import Clock
    clocks = test_node.collect(Clock, '/clock')
    test_node.spin_until(lambda: bool(clocks), 90, 'the run to start (/clock)')


def test_sigterm_stops_every_child_cleanly_and_the_sim_does_not_listen_to_its_own_clock(launch, test_node):
    run = launch('bringup', 'spin', '--real-time-factor', '4')
    wait_until_running(test_node)
    node = test_node.node
    test_node.spin_until(lambda: node.get_subscriptions_info_by_topic('/clock'), 30, 'a /clock subscriber')
    assert [info.node_name for info in node.get_subscriptions_info_by_topic('/clock')
            if info.node_name == 'sim'] == []
    children = child_pids()
    assert len(children) == 2, processes_in_this_domain()
    run.proc.send_signal(signal.SIGTERM)
    assert run.proc.wait(timeout=60) == 0, run.output()
    assert 'error' not in run.output().lower(), run.output()
    assert processes_in_this_domain() == []


def test_sigkill_of_bringup_ends_every_child(launch, test_node, tmp_path):
    run = launch('bringup', 'avoid', '--real-time-factor', '2', '--record', str(tmp_path / 'killed'))
    wait_until_running(test_node)
    children = child_pids()
    assert len(children) == 3, processes_in_this_domain()  # sim, recorder, avoid
    os.kill(run.proc.pid, signal.SIGKILL)
    run.proc.wait(timeout=10)
    assert wait_until_gone(children, timeout=60) == [], processes_in_this_domain()


def test_a_dying_behaviour_stops_the_rest_and_fails_the_run(launch, test_node):
    run = launch('bringup', 'circle', '--real-time-factor', '4')
    wait_until_running(test_node)
    (pid,) = [pid for pid, cmd in processes_in_this_domain() if re.search(r'/circle\b', cmd)]
    os.kill(pid, signal.SIGKILL)
    assert run.proc.wait(timeout=60) == 1
    assert run.output().count('circle exited unexpectedly with code -9') == 1, run.output()
    assert 'simulated' not in run.output()
    assert processes_in_this_domain() == []


@pytest.mark.parametrize('discovered', [True, False], ids=['other-sim-discovered', 'other-sim-just-started'])
def test_another_simulator_on_the_domain_is_refused(launch, test_node, discovered):
    """Whether or not the other simulator is past its discovery window (silent in it) when bringup starts, the run
    is refused: it must never run on the other one's clock."""
    other = launch('sim')
    if discovered:
        test_node.spin_until(lambda: test_node.node.count_publishers('/clock') == 1, 60, "the other sim's /clock")
    run = launch('bringup', 'forward', '--duration', '2')
    # Seen before any child starts: exit 2, nothing started; seen only later (still silent): the run fails, exit 1.
    assert run.proc.wait(timeout=90) in ((2,) if discovered else (1, 2)), run.output()
    assert 'another simulator' in run.output()
    assert 'simulated' not in run.output()
    assert [pid for pid, _ in processes_in_this_domain()] == [other.proc.pid]


def test_a_second_bringup_on_the_domain_starts_nothing_and_the_first_run_is_untouched(launch, test_node):
    """Started 3 s into another run, a second bringup's avoid drove the first's robot before its simulator refused,
    or the first was aborted. It now looks at the domain before starting anything: exit 2, and the first run ends
    exactly as a lone run with the same seed."""
    lone = launch('bringup', 'avoid', '--duration', '6', '--real-time-factor', '0', '--seed', '4')
    assert lone.proc.wait(timeout=120) == 0, lone.output()
    from rosgraph_msgs.msg import Clock
    ticks = test_node.collect(Clock, '/clock')
    first = launch('bringup', 'avoid', '--duration', '6', '--real-time-factor', '1', '--seed', '4')
    test_node.spin_until(lambda: any(tick.clock.sec >= 1 for tick in ticks), timeout=120,
                         what="the first run's /clock past 1 s")
    # Paused while the second tries, however long a loaded machine takes to start it (lockstep: the run is the same)
    set_sim_parameter(test_node, first, 'paused', True)
    second = launch('bringup', 'avoid', '--duration', '6', '--real-time-factor', '0', '--seed', '9')
    assert second.proc.wait(timeout=120) == 2, second.output()
    assert 'another simulator is running on this ROS domain' in second.output()
    assert 'nothing was started' in second.output() and 'Traceback' not in second.output()
    set_sim_parameter(test_node, first, 'real_time_factor', 0.0)   # the rest as fast as it goes (lockstep: same run)
    set_sim_parameter(test_node, first, 'paused', False)
    assert first.proc.wait(timeout=120) == 0, first.output()
    assert '[bringup] reproducible: every step' in first.output(), first.output()
    assert summary_of(first.output())[1:] == summary_of(lone.output())[1:], (first.output(), lone.output())


def test_avoid_for_a_simulated_minute_without_a_collision(launch):
    """Noise on, default world, through real processes, in lockstep: the bound is the one of test_behaviours'
    pure runs (cruising at 0.0628 m/s at least half of the time gives > 1.88 m; spinning in place gives ~0)."""
    run = launch('bringup', 'avoid', '--duration', '60', '--real-time-factor', '0', '--seed', '5')
    assert run.proc.wait(timeout=300) == 0, run.output()
    simulated, distance, collisions = summary_of(run.output())
    assert simulated == pytest.approx(60.0, abs=0.032)
    assert collisions == 0
    assert distance > 0.0628 * 30


def test_the_summary_is_the_bag_summary_and_lockstep_runs_are_identical(launch, tmp_path):
    """Noise on, seed fixed: two recorded runs give the same trajectory to the last bit, and bringup's figures are
    the ones `bag summary` prints for the same bag. Far more steps than the simulator runs ahead of a recorder's
    acknowledgements (`ack_window.SHORT_WINDOW`), and long enough that a recorder taking one message per topic and
    turn fell behind on `proximity` (eight per step) and lost most of it: every message is in the bag."""
    from epuck_ros.bag.reader import Bag
    from epuck_ros.ros.ack_window import SHORT_WINDOW
    steps = 1600
    assert steps > 4 * SHORT_WINDOW
    trajectories, distances = [], []
    for run_index in range(2):
        bag = tmp_path / f'run{run_index}'
        run = launch('bringup', 'avoid', '--duration', f'{steps * 0.032:g}', '--real-time-factor', '0', '--seed', '3',
                     '--record', str(bag))
        assert run.proc.wait(timeout=300) == 0, run.output()
        assert 'no message lost' in run.output(), run.output()   # the recorder's own check, wheel_cmd included
        simulated, distance, _ = summary_of(run.output())
        assert simulated == pytest.approx(steps * 0.032, abs=0.032)
        bag_summary = subprocess.run([str(BIN_DIR / 'bag'), 'summary', str(bag)], capture_output=True, text=True,
                                     timeout=60)
        assert bag_summary.returncode == 0, bag_summary.stderr
        bag_distance = float(re.search(r'Distance:\s+([\d.]+) m', bag_summary.stdout)[1])
        assert f'{distance:.3f}' == f'{bag_distance:.3f}', (run.output(), bag_summary.stdout)
        distances.append(distance)
        with Bag(bag) as reader:
            messages = [m.data for m in reader.messages(topics=['/ground_truth'])]
            assert reader.topics['/proximity'].message_count >= 8 * steps
        # In lockstep the sim may re-send its first step until the behaviour answers: drop such repeats.
        trajectories.append([data for i, data in enumerate(messages) if i == 0 or data != messages[i - 1]])
    assert [len(t) for t in trajectories] == [steps] * 2
    differ = [i for i, (a, b) in enumerate(zip(*trajectories)) if a != b]
    assert not differ, f'{len(differ)} steps differ, the first at step {differ[0] + 1}'
    assert distances[0] == distances[1] > 0.2


def test_the_summary_prints_the_shape_figures_of_bag_summary(launch, tmp_path):
    """The `bringup` summary said it printed `bag summary`'s figures but left out the shape's: the corners
    of a timed rectangle (31 steps of 32 ms per turn: 82.4 degrees) and the circle fit, from the same code,
    recorded or not."""
    rectangle = launch('bringup', 'rectangle', '--duration', '30', '--real-time-factor', '0', '-p', 'turn_mode:=timed',
                       '--record', str(tmp_path / 'rect'))
    assert rectangle.proc.wait(timeout=120) == 0, rectangle.output()
    bag_summary = subprocess.run([str(BIN_DIR / 'bag'), 'summary', str(tmp_path / 'rect')], capture_output=True,
                                 text=True, timeout=60)
    corners = re.search(r'Corners:\s+(.+)', bag_summary.stdout)[1]
    assert f'[bringup]   Corners: {corners}' in rectangle.output(), (rectangle.output(), bag_summary.stdout)
    assert '82.4°, 82.4°, 82.4°, 82.4°' in corners
    circle = launch('bringup', 'circle', '--duration', '10', '--real-time-factor', '0')
    assert circle.proc.wait(timeout=120) == 0, circle.output()
    assert re.search(r'\[bringup\]   Circle fit: radius 0\.078\d m', circle.output()), circle.output()


def test_several_robots_one_behaviour_process_a_table_per_robot(launch, tmp_path):
    run = launch('bringup', 'avoid', '--robots', '3', '--duration', '3', '--real-time-factor', '0', '--seed', '2',
                 '--record', str(tmp_path / 'swarm'))
    assert run.proc.wait(timeout=120) == 0, run.output()
    rows = ROBOT.findall(run.output())
    assert [name for name, _, _ in rows] == ['epuck0', 'epuck1', 'epuck2'], run.output()
    assert all(float(distance) > 0.05 for _, distance, _ in rows), run.output()
    assert '[bringup] running avoid on 3 robots' in run.output()
    assert processes_in_this_domain() == []


def test_an_rclpy_controller_script_runs_with_sim_time_and_gets_the_summary(launch, tmp_path):
    script = rclpy_script(tmp_path / 'my_node.py', '''
        """A student's own node: both wheels at 2 rad/s on every simulated tick."""
        from std_msgs.msg import Float64MultiArray

        node = rclpy.create_node('my_node')
        assert node.get_parameter('use_sim_time').value
        publisher = node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
        node.create_timer(0.032, lambda: publisher.publish(Float64MultiArray(data=[2.0, 2.0])))
    ''')
    run = launch('bringup', '--controller', str(script), '--duration', '3', '--real-time-factor', '0', '--no-noise')
    assert run.proc.wait(timeout=90) == 0, run.output()
    simulated, distance, _ = summary_of(run.output())
    assert simulated == pytest.approx(3.0, abs=0.032)
    # 2 rad/s wheels: 0.04 m/s while commanded (a plain script may hear the first /clock ticks late: it does not
    # wait for its step's data as the behaviour nodes do).
    assert 0.04 * simulated / 2 < distance <= 0.04 * simulated + 1e-3, run.output()
    assert processes_in_this_domain() == []


def test_a_controller_at_its_own_rate_is_not_held_to_lockstep(launch, tmp_path):
    """The most common ROS pattern, cmd_vel from a 10 Hz timer on simulated time, cannot answer the first step (its
    timer waits for time to move), and plain Twist cannot name a step: the sim never waits for its first answer (it
    waited FIRST_ANSWER_WAIT, 10 s, before issue 33 item 6), only briefly at each step, and says so once its commands
    drive: the run reaches its duration with the robot driven as commanded, and the summary says it is not
    reproducible."""
    script = rclpy_script(tmp_path / 'ten_hertz.py', '''
        from geometry_msgs.msg import Twist

        node = rclpy.create_node('ten_hertz')
        publisher = node.create_publisher(Twist, 'cmd_vel', 10)
        command = Twist()
        command.linear.x = 0.05
        node.create_timer(0.1, lambda: publisher.publish(command))
    ''')
    run = launch('bringup', '--controller', str(script), '--duration', '6', '--real-time-factor', '0', '--no-noise')
    assert run.proc.wait(timeout=120) == 0, run.output()
    assert 'did not answer its first step' not in run.output() and 'sending it again' not in run.output()
    assert 'a lockstep controller answers each step naming it' in run.output()
    assert '[bringup] not reproducible: the controller of epuck sends commands that name no step' in run.output()
    simulated, distance, _ = summary_of(run.output())
    assert simulated == pytest.approx(6.0, abs=0.032)
    assert distance == pytest.approx(0.05 * 6, abs=0.02), run.output()   # 0.05 m/s from about the first 0.1 s
    assert processes_in_this_domain() == []


def test_a_child_printing_a_huge_line_keeps_bringup_small(launch, tmp_path):
    r"""A child printing 200 MB without a newline took bringup to 800 MB; a `\r` progress line grew without bound.
    Forwarding reads in chunks and cuts a line at 64 KiB: bringup's peak memory (VmHWM) stays far below 200 MB."""
    script = tmp_path / 'chatty.py'
    script.write_text(textwrap.dedent('''
        import sys
        import rclpy
        from std_msgs.msg import Float64MultiArray

        rclpy.init()
        node = rclpy.create_node('chatty')
        for _ in range(200):
            sys.stdout.write('x' * 1_000_000)
        for done in range(5):
            sys.stdout.write(f'progress {done}/5\\r')
        sys.stdout.write('\\nlast line\\n')
        sys.stdout.flush()
        # Only now a controller in the graph: bringup resumes the simulation once it sees one
        publisher = node.create_publisher(Float64MultiArray, 'wheel_cmd', 10)
        node.create_timer(0.032, lambda: publisher.publish(Float64MultiArray(data=[1.0, 1.0])))
        rclpy.spin(node)
    '''))
    run = launch('bringup', '--controller', str(script), '--duration', '1', '--real-time-factor', '0')
    peak = 0
    while run.proc.poll() is None:
        status = Path(f'/proc/{run.proc.pid}/status')
        try:
            peak = max(peak, int(re.search(r'VmHWM:\s+(\d+) kB', status.read_text())[1]))
        except (OSError, TypeError):
            pass
        time.sleep(0.05)
    assert run.proc.returncode == 0, run.output()[-3000:]
    output = run.output()
    assert '[... cut: a line of over 64 KiB]' in output and '[chatty.py] progress 4/5' in output
    assert '[chatty.py] last line' in output and len(output) < 2_000_000
    assert 0 < peak < 150_000, f'bringup peaked at {peak} kB'


def test_a_webots_controller_script_runs_through_webots_controller(launch):
    script = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples' / 'straight_line.py'
    run = launch('bringup', '--controller', str(script), '--duration', '3', '--real-time-factor', '0', '--no-noise')
    assert run.proc.wait(timeout=90) == 0, run.output()
    simulated, distance, _ = summary_of(run.output())
    # Half speed (0.0628 m/s) from the first step to the last, as the native `forward`.
    assert distance == pytest.approx(0.0628 * (simulated - 0.032), abs=2e-3)
    assert processes_in_this_domain() == []


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def test_run_sh_view_starts_the_default_run_with_the_view_and_prints_its_url(tmp_path):
    """What a newcomer types: `scripts/run.sh --view` (here on a free port), then opens the printed address."""
    port = free_port()
    log_path = tmp_path / 'run.log'
    root = Path(__file__).resolve().parents[1]
    with open(log_path, 'w') as log:
        process = subprocess.Popen([str(root / 'scripts' / 'run.sh'), '--view', '-p', f'view.port:={port}'],
                                   stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        url = f'http://127.0.0.1:{port}/'
        deadline = time.monotonic() + 120
        while f'[bringup] view: {url}' not in log_path.read_text():
            assert process.poll() is None and time.monotonic() < deadline, log_path.read_text()
            time.sleep(0.1)
        assert '[bringup] running avoid until Ctrl-C' in log_path.read_text()
        with urllib.request.urlopen(url, timeout=60) as response:
            assert response.status == 200 and b'<html' in response.read().lower()
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=60) == 0, log_path.read_text()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert '[bringup] simulated' in log_path.read_text()
    assert processes_in_this_domain() == []


def test_readiness_does_not_depend_on_what_the_children_log(launch, monkeypatch, tmp_path):
    """Every log line of every child reduced to its severity: bringup still sees each process come up (from the
    graph) and the recorded run is complete."""
    monkeypatch.setenv('RCUTILS_CONSOLE_OUTPUT_FORMAT', '{severity}')
    run = launch('bringup', 'spin', '--duration', '2', '--real-time-factor', '0', '--record', str(tmp_path / 'bag'))
    assert run.proc.wait(timeout=90) == 0, run.output()
    assert 'sim ready' not in run.output() and 'Recording' not in run.output()
    assert SIMULATED.search(run.output())[1] == '2.02'


SLOW_PARAMETER_SERVER = '''
import sys, threading, rclpy
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
rclpy.init()
node = Node('sim', start_parameter_services=False)
first = threading.Event()
def answer(request, response):
    print('request', flush=True)
    if not first.is_set():  # the first request is answered only once the test is over: as if it were lost
        first.set()
        threading.Event().wait(600)
    response.results = [SetParametersResult(successful=True)]
    return response
node.create_service(SetParameters, 'sim/set_parameters', answer, callback_group=ReentrantCallbackGroup())
print('ready', flush=True)
rclpy.spin(node, MultiThreadedExecutor(num_threads=2))
'''


def test_an_unanswered_resume_is_asked_again():
    """A first request to a just-discovered service can go unanswered; bringup asks again instead of failing the run."""
    from rcl_interfaces.srv import SetParameters

    from epuck_ros.bringup.monitor import REQUEST_RETRY, RunMonitor
    server = subprocess.Popen([sys.executable, '-c', SLOW_PARAMETER_SERVER], stdout=subprocess.PIPE, text=True)
    monitor = RunMonitor('', '', follow_robots=False)
    try:
        assert server.stdout.readline().strip() == 'ready'
        service = monitor.node.create_client(SetParameters, '/sim/set_parameters')  # the one service it offers
        deadline = time.monotonic() + 60
        while not service.service_is_ready() and time.monotonic() < deadline:
            monitor.spin(0.05)
        assert monitor.set_paused(False, 30 * REQUEST_RETRY)
    finally:
        monitor.close()
        server.kill()  # its first request's thread still waits
        out, _ = server.communicate(timeout=30)
    assert out.count('request') >= 2, out  # the first one, never answered, and the one sent again
