"""Edges a newcomer hit: bringup's summary from every step, with each robot's final pose (bringup and `bag summary`),
`bag play`'s wait said and chosen, a second simulator's refusal, `record` alone, IPv6 addresses, a closed pipe, the
fixture's executables and domains (issue 33, items 11, 12, 14, 15 and 16)."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import BIN_DIR

from epuck_ros.bag.summary_text import format_figures
from epuck_ros.experiments.trial import Controller, Trial, run, run_trial


def busy_loops() -> list[subprocess.Popen]:
    """One spinning process per core: the load under which a KEEP_LAST reader skipped steps."""
    return [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(2)]


def test_bringup_s_monitor_misses_no_step_however_long_it_does_not_read(launch, test_node):
    """Item 11: bringup's monitor not reading for as long as the simulator runs ahead (a loaded machine, taken to
    the extreme): the simulator waits for it, and every step's ground truth arrives. Measured: the simulator stood
    still at step 7,500 (the reader's 5,000 samples, Fast DDS's default, plus the simulator's window) until the
    monitor read again. (The former KEEP_LAST reader of depth 10,000 was held the same way by that resource limit,
    so this guards the property rather than failing on the former code.) The simulator stops waiting for a reader
    that acknowledged nothing for `ack_window.GIVE_UP` (a hung process): the monitor reads again after half that at
    most. The test's own `/clock` reader keeps only the newest tick: one that kept 100 got no tick at all for the
    10 s the simulator stood still, in 5 of 23 runs beside three busy loops, and the monitor read too late."""
    from rosgraph_msgs.msg import Clock

    from epuck_ros.bringup.monitor import RunMonitor, samples_missing
    from epuck_ros.ros.ack_window import GIVE_UP
    steps, time_step = 12_000, 0.032
    end = steps * time_step
    launch('sim', '--ros-args', '-p', 'paused:=true', '-p', f'pause_at:={end}', '-p', 'discovery_window:=0.0',
           '-p', 'real_time_factor:=0.0')
    monitor = RunMonitor('', '')
    try:
        deadline = time.monotonic() + 60
        while monitor.sim_missing() and time.monotonic() < deadline:
            monitor.spin(0.1)
        assert not monitor.sim_missing(), monitor.sim_missing()
        ticks = test_node.collect(Clock, '/clock', 1)
        assert monitor.set_paused(False, 60)
        seen = [0.0, time.monotonic()]
        read_again = time.monotonic() + GIVE_UP / 2

        def ended_or_held() -> bool:
            """The simulator at its end, or standing still for a second (waiting for the monitor), or the most the
            monitor may stay silent."""
            latest = ticks[-1].clock.sec + ticks[-1].clock.nanosec * 1e-9 if ticks else 0.0
            if latest != seen[0]:
                seen[:] = [latest, time.monotonic()]
            return latest >= end - 1e-6 or (latest > 0 and time.monotonic() - seen[1] > 1.0) or \
                time.monotonic() >= read_again

        test_node.spin_until(ended_or_held, timeout=600, what='the simulator at its end or held')
        monitor.spin(600, until_sim_time=end)
        monitor.catch_up(60)
        [track] = monitor.tracks.values()
        assert monitor.sim_time == pytest.approx(end)
        assert samples_missing(track, time_step, monitor.sim_time) == 0, len(track.stamps)
    finally:
        monitor.close()


def test_bringup_s_monitor_takes_what_its_executor_is_not_told_of(test_node):
    """Should rclpy's EventsExecutor not be told of a message (suspected first when the monitor's `/clock` stalled:
    see the next test), the monitor asks its readers itself. Here its executor is told of nothing at all: the node
    is taken off it."""
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock

    from epuck_ros.bringup.monitor import RunMonitor
    from epuck_ros.ros.qos import CLOCK_KEPT
    clock = test_node.node.create_publisher(Clock, '/clock', CLOCK_KEPT)
    monitor = RunMonitor('', '')
    try:
        monitor._executor.remove_node(monitor.node)
        test_node.spin_until(lambda: clock.get_subscription_count() > 0, what="the monitor's /clock reader")
        for step in range(1, 31):
            clock.publish(Clock(clock=Time(sec=step, nanosec=0)))
        monitor.spin(60, until_sim_time=30.0)
        assert monitor.sim_time == 30.0
    finally:
        monitor.close()


def test_bringup_s_monitor_makes_a_stalled_clock_reader_anew(test_node):
    """The monitor's `/clock` reader once heard nothing more after 240 s of 384, for 600 s, though nothing waited in
    it and the simulator had gone on to its end (the first test here, loaded); a new reader got the ticks at once.
    Here the reader is destroyed under the monitor's feet after the first tick: the monitor makes a new one, which
    gets the ticks kept for it and drops those heard already."""
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock

    from epuck_ros.bringup.monitor import RunMonitor
    from epuck_ros.ros.qos import CLOCK_KEPT
    clock = test_node.node.create_publisher(Clock, '/clock', CLOCK_KEPT)
    monitor = RunMonitor('', '')
    try:
        test_node.spin_until(lambda: clock.get_subscription_count() > 0, what="the monitor's /clock reader")
        clock.publish(Clock(clock=Time(sec=1, nanosec=0)))
        monitor.spin(20, until_sim_time=1.0)
        assert monitor.sim_time == 1.0
        [reader] = [reader for reader in monitor.node.subscriptions if reader.topic_name == '/clock']
        monitor.node.destroy_subscription(reader)
        for step in range(2, 31):
            clock.publish(Clock(clock=Time(sec=step, nanosec=0)))
        monitor.spin(20, until_sim_time=30.0)
        assert monitor.sim_time == 30.0
        assert monitor.clock_messages == 1 + CLOCK_KEPT.depth   # the first, then the last ticks kept
    finally:
        monitor.close()


def test_bringup_s_monitor_waits_until_the_recorder_heard_every_controller_it_heard_declare(test_node):
    """A recorded run is resumed once the recorder has heard from each controller that declared itself (a loaded
    `bringup --record` of a 2 s swarm run was over before the controller had matched the recorder: no answer in the
    bag): from a per-robot declaration, and from a swarm controller's declaration on `swarm/command`."""
    import numpy as np
    from std_msgs.msg import Float64MultiArray, String

    from epuck_ros.bringup.monitor import RunMonitor
    from epuck_ros.lockstep import DECLARATION_TOPIC
    from epuck_ros.ros.qos import LATCHED, declarations_kept
    from epuck_ros.ros.recorder_heard import HEARD_TOPIC, heard_text
    from epuck_ros.swarm_messages import COMMAND_TOPIC, SwarmLayout
    monitor = RunMonitor('', '')
    node = test_node.node
    heard = node.create_publisher(String, HEARD_TOPIC, LATCHED)
    try:
        assert monitor.recorder_heard()   # nobody declared: nothing to wait for
        declarations = node.create_publisher(String, DECLARATION_TOPIC, declarations_kept(1))
        declarations.publish(String(data='lockstep /epuck0/wheel_cmd'))
        swarm = node.create_publisher(Float64MultiArray, '/' + COMMAND_TOPIC, LATCHED)
        swarm.publish(SwarmLayout(('epuck1',), ()).to_bytes(np.zeros((1, 0)), None))
        spin_monitor_until(monitor, lambda: monitor._recorder_heard.declared and monitor._swarm.declared,
                           'the declarations')
        heard.publish(String(data=heard_text(['/epuck0/wheel_cmd'])))
        spin_monitor_until(monitor, lambda: monitor._recorder_heard.topics, "the recorder's first word")
        assert not monitor.recorder_heard()   # not the swarm controller yet
        heard.publish(String(data=heard_text(['/epuck0/wheel_cmd', '/swarm/command'])))
        spin_monitor_until(monitor, monitor.recorder_heard, 'the recorder to have heard both')
        heard.publish(String(data='x' * 5_000_000))   # anyone may publish there: read as nothing, no crash
        spin_monitor_until(monitor, lambda: not monitor.recorder_heard(), 'a forged word read as nothing')
    finally:
        monitor.close()


def spin_monitor_until(monitor, predicate, what: str, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f'timed out waiting for {what}'
        monitor.spin(0.05)


def test_bringup_s_summary_under_load_is_the_headless_run_s(launch):
    """Items 11 and 16: not recorded, beside a busy loop on each core, bringup's figures (distance, duration,
    contacts, final pose) are those of the same run headless, to the printed digit: its ground-truth reader keeps
    all (`ros.qos.EVERY_STEP`), so the simulator waits for it (a KEEP_LAST reader is not waited for)."""
    duration = 20.0
    _, tally = run(Trial(Controller('avoid'), seed=3, duration=duration))
    expected = format_figures(tally.figures)
    assert re.fullmatch(r'[\d.]+ m in [\d.]+ s, \d+ contacts? with walls/obstacles; final pose x -?[\d.]+ m, '
                        r'y -?[\d.]+ m, yaw -?[\d.]+ rad \(-?[\d.]+°\)', expected), expected
    loops = busy_loops()
    try:
        bringup = launch('bringup', 'avoid', '--duration', f'{duration:g}', '--real-time-factor', '0', '--seed', '3')
        assert bringup.proc.wait(timeout=300) == 0, bringup.output()
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
    assert f'[bringup] {expected}\n' in bringup.output(), (expected, bringup.output())
    assert 'did not arrive' not in bringup.output()


def bag_summary(path) -> str:
    result = subprocess.run([str(BIN_DIR / 'bag'), 'summary', str(path)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_bag_summary_gives_each_robot_s_final_pose(tmp_path):
    """Item 16: `bag summary` says where each robot ended, as the sweep's CSV has it (final_x, final_y, final_yaw)."""
    one = tmp_path / 'one'
    [row] = run_trial(Trial(Controller('avoid'), seed=3, duration=5.0, record=str(one)))
    assert not row['error'], row
    pose = re.search(r'Final pose:\s+x (\S+) m, y (\S+) m, yaw (\S+) rad', bag_summary(one))
    assert pose, bag_summary(one)
    assert [float(value) for value in pose.groups()] == [round(row[f'final_{axis}'], 4) for axis in 'xy'] + \
        [round(row['final_yaw'], 4)]
    three = tmp_path / 'three'
    rows = run_trial(Trial(Controller('avoid'), robots=3, seed=2, duration=3.0, record=str(three)))
    table = [re.split(r'\s{2,}', line.strip()) for line in bag_summary(three).split('\n\n', 1)[1].splitlines()]
    columns = [table[0].index(name) for name in ('final x m', 'final y m', 'final yaw rad')]
    robots = [cells for cells in table[1:] if cells[0].startswith('/')]
    assert [cells[0] for cells in robots] == [f'/{row["robot"]}' for row in rows]
    for row, cells in zip(rows, robots):
        assert [float(cells[i]) for i in columns] == [round(row[name], 4)
                                                      for name in ('final_x', 'final_y', 'final_yaw')]


@pytest.mark.parametrize('count, text', [(0, '0 contacts'), (1, '1 contact with'), (2, '2 contacts')])
def test_one_contact_is_singular(count, text):
    """Item 14: '1 contacts' was printed."""
    from epuck_ros.bag.tally import RobotFigures
    line = format_figures([RobotFigures('', world_contacts=count, last_pose=(0.0, 0.0, 0.0))])
    assert f', {text}' in line, line


def test_a_clock_source_not_yet_known_by_name_is_named_by_its_announcement():
    """Item 14: bringup's refusal named the other simulator `_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_` (DDS had
    not told its name yet); it now says its pid, host and start time, as `sim` alone does."""
    import time

    from epuck_ros.bringup.monitor import unknown_named_by
    from epuck_ros.ros.announcements import announcement
    unknown = '_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_'
    other = announcement(time.time_ns(), 4242)
    [said] = unknown_named_by([unknown], [other])
    assert said.startswith(f'the simulator pid 4242 on {other.host}, started {time.strftime("%Y-%m-%d")} '), said
    assert unknown_named_by(['/sim', unknown], []) == ['/sim', 'a node not yet known by name']
    assert unknown_named_by(['/sim'], [other]) == ['/sim']


def test_foxglove_addresses_ipv6_in_brackets_and_127_1_is_loopback(launch):
    """Item 14: `foxglove --host ::` printed `ws://:::PORT`; `--host 127.1` (127.0.0.1) was warned as reachable from
    other machines."""
    from epuck_ros.foxglove.address import websocket_url
    from epuck_ros.loopback import is_loopback
    assert websocket_url('::', 8793) == 'ws://[::]:8793' and websocket_url('::1', 1) == 'ws://[::1]:1'
    assert websocket_url('127.0.0.1', 8765) == 'ws://127.0.0.1:8765'
    assert websocket_url('localhost', 8765) == 'ws://localhost:8765'
    assert all(is_loopback(host) for host in ('127.1', '127.0.0.1', 'localhost', '::1', '127.0.0.2'))
    assert not any(is_loopback(host) for host in ('0.0.0.0', '::', '192.0.2.1', 'no.such.host.invalid'))
    wide = launch('foxglove', '--host', '::', '--port', '0')
    wide.wait_for_output('foxglove: ws://[::]:', timeout=60)
    assert 'any machine that reaches this one' in wide.output()
    local = launch('foxglove', '--host', '127.1', '--port', '0')
    local.wait_for_output('foxglove: ws://127.1:', timeout=60)
    assert 'warning' not in local.output(), local.output()


def test_headless_output_into_a_closed_pipe_ends_without_a_traceback():
    """Item 14: `webots_controller ... --headless --robots 3 | head -1` ended in a BrokenPipeError traceback. Here the
    reader is gone before anything is written: the run ends, quietly, as `bag csv ... | head` does."""
    from pathlib import Path
    script = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples' / 'avoid_obstacles.py'
    run_ = subprocess.Popen([str(BIN_DIR / 'webots_controller'), str(script), '--headless', '--robots', '3',
                             '--duration', '2'], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    run_.stdout.close()
    _, stderr = run_.communicate(timeout=120)
    assert run_.returncode == 0 and b'Traceback' not in stderr and b'BrokenPipe' not in stderr, stderr.decode()


CTRL_C_AT_EXIT = """
import atexit, signal, sys
from pathlib import Path
def ctrl_c_ignored_at_exit():   # registered first: runs last, when Python is about to give SIGINT its default back
    fields = dict(line.split(':', 1) for line in Path('/proc/self/status').read_text().splitlines() if ':' in line)
    print('ignored' if int(fields['SigIgn'], 16) & (1 << (signal.SIGINT - 1)) else 'default', flush=True)
atexit.register(ctrl_c_ignored_at_exit)
{body}
"""


@pytest.mark.parametrize('body', [
    'from epuck_ros.ros.spinning import handle_shutdown_signals\nhandle_shutdown_signals()',
    'from epuck_ros.bag_cli import main\nmain(["play", sys.argv[1], "--wait", "0", "--rate", "1000"])',
    'from epuck_ros.experiments.cli import main\ntry:\n    main(["--help"])\nexcept SystemExit:\n    pass',
    'from epuck_ros.evolution.cli import main\ntry:\n    main(["--help"])\nexcept SystemExit:\n    pass',
])
def test_a_ctrl_c_while_a_command_ends_by_itself_is_ignored(body, tmp_path):
    """`bag play` and `sweep` once exited with status -2 in loaded suite runs: their Ctrl-C came as they were ending by
    themselves, in Python's exit, which gives SIGINT its default action back. Once the program of a node, `bag play`,
    `sweep` or `evolve` has returned, SIGINT is ignored, as the process's exit shows."""
    bag = Path(__file__).resolve().parents[1] / 'bags' / 'spin'
    ended = subprocess.run([sys.executable, '-c', CTRL_C_AT_EXIT.format(body=body), str(bag)], capture_output=True,
                           text=True, timeout=120)
    assert ended.returncode == 0, ended.stderr
    assert ended.stdout.splitlines()[-1] == 'ignored', ended.stdout
