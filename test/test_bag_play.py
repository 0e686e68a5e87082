"""`bag play`: the pacing schedule (pure), the replay QoS, and real replays over DDS re-recorded by `record`.

The re-recorded bag is read with the mcap library and mcap_ros2's decoder, not the project's reader.
"""
from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from epuck_ros.bag.play import PLAY_DEPTH, PlaybackClock, replay_profile, schedule
from epuck_ros.bag.qos import QosProfile, profiles_to_yaml

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / 'bags' / 'spin'
"""A 4 s recording of every sim topic (1,508 messages besides /clock)."""
NOT_COMPARED = ('/clock', '/parameter_events')
"""The player publishes its own /clock; the recorder and player nodes publish parameter events of their own."""
BAG = str(Path(sys.executable).parent / 'bag')


# --- pacing and QoS, no ROS -----------------------------------------------------------------------------

def test_rate_2_halves_the_wall_time_of_every_message():
    log_times = [5_000_000_000 + k * 32_000_000 for k in range(126)]
    at_1, at_2 = schedule(log_times, 1.0), schedule(log_times, 2.0)
    assert at_1[0] == at_2[0] == 0.0
    assert at_1[-1] == pytest.approx(4.0)
    assert at_2 == pytest.approx([t / 2 for t in at_1])
    assert schedule(log_times, 0.5)[-1] == pytest.approx(8.0)


def test_pausing_freezes_bag_time_and_shifts_what_is_due():
    clock = PlaybackClock(start_ns=10**9, rate=2.0, now=100.0)
    assert clock.due(3 * 10**9) == pytest.approx(101.0)  # 2 s of bag at rate 2
    clock.pause(100.5)
    assert clock.bag_time(100.5) == clock.bag_time(150.0) == 2 * 10**9
    assert clock.due(3 * 10**9) == math.inf
    clock.resume(160.0)
    assert clock.due(3 * 10**9) == pytest.approx(160.5)
    assert clock.bag_time(160.25) == 2_500_000_000
    clock.restart(10**9, 200.0)  # the next loop
    assert clock.bag_time(200.0) == 10**9 and clock.due(2 * 10**9) == pytest.approx(200.5)
    with pytest.raises(ValueError, match='rate'):
        PlaybackClock(0, 0.0, 0.0)


def test_replay_qos_follows_what_the_publishers_offered():
    latched = profiles_to_yaml([QosProfile(history='unknown', depth=0, durability='transient_local')])
    assert replay_profile(latched) == QosProfile(depth=PLAY_DEPTH, durability='transient_local')
    mixed = profiles_to_yaml([QosProfile(durability='transient_local'), QosProfile(reliability='best_effort')])
    assert replay_profile(mixed) == QosProfile(depth=PLAY_DEPTH)
    best_effort = profiles_to_yaml([QosProfile(reliability='best_effort')])
    assert replay_profile(best_effort).reliability == 'best_effort'
    assert replay_profile('') == replay_profile('not: [yaml') == QosProfile(depth=PLAY_DEPTH)


def test_bad_arguments_are_one_line_and_exit_2(tmp_path):
    for args, message in ((['--rate', '0'], 'must be from 0.001 to 1000'), (['--rate', 'fast'], 'expected a number'),
                          (['--rate', '1e308'], 'must be from 0.001 to 1000'), (['--rate', 'nan'], 'must be from'),
                          (['--clock', '1e-300'], 'must be from 0.1 to 10000'), (['--wait', '-1'], 'must be from 0'),
                          (['--wait', 'nan'], 'must be from 0')):
        result = subprocess.run([BAG, 'play', str(SAMPLE), *args], capture_output=True, text=True, timeout=60)
        assert result.returncode == 2 and message in result.stderr and 'Traceback' not in result.stderr, args
    result = subprocess.run([BAG, 'play', str(tmp_path / 'none')], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and result.stderr.count('\n') == 1 and 'no such bag' in result.stderr


# --- over DDS -------------------------------------------------------------------------------------------

def read_back(path: Path) -> dict[str, list[tuple[bytes, object]]]:
    """Map topic -> [(CDR bytes, decoded message)] in log order, with mcap's reader and mcap_ros2's decoder."""
    topics: dict[str, list] = {}
    files = sorted(path.glob('*.mcap'))
    assert files, f'no mcap file in {path}'
    for file in files:
        with open(file, 'rb') as handle:
            reader = make_reader(handle, decoder_factories=[DecoderFactory()])
            for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
                topics.setdefault(channel.topic, []).append((message.data, decoded))
    return topics


def wait_for_exit(process, timeout: float = 120.0) -> int:
    """The process's exit code once it ends by itself (a generous bound against a hang, not a timing test)."""
    return process.proc.wait(timeout=timeout)


def test_a_played_bag_re_recorded_gives_the_same_messages(launch, test_node, tmp_path):
    source = read_back(SAMPLE)
    played = sorted(set(source) - set(NOT_COMPARED))
    recorder = launch('record', '-o', str(tmp_path / 'again'))
    player = launch('bag', 'play', str(SAMPLE), '--rate', '4', '--start-paused')
    node = test_node.node
    test_node.spin_until(lambda: all(node.count_subscribers(t) >= 1 and node.count_publishers(t) >= 1
                                     for t in played + ['/clock']),
                         timeout=60, what='the recorder subscribed to every played topic')
    from std_srvs.srv import Trigger
    resume = node.create_client(Trigger, '/bag_player/resume')
    assert resume.wait_for_service(timeout_sec=30)
    started = time.monotonic()
    future = resume.call_async(Trigger.Request())
    test_node.spin_until(future.done, timeout=30, what='the resume service')
    assert future.result().success
    assert wait_for_exit(player) == 0, player.output()
    wall = time.monotonic() - started
    assert recorder.stop() == 0, recorder.output()
    # Issue 33 item 14: the player's /clock ticks were at wall instants, their stamps irregular: 'lost' to the recorder
    said = recorder.log_path.read_text()
    assert not [line for line in said.splitlines() if 'lost' in line and '/clock' in line], said
    again = read_back(tmp_path / 'again')
    for topic in played:
        assert [data for data, _ in again.get(topic, [])] == [data for data, _ in source[topic]], topic
        if hasattr(source[topic][0][1], 'header'):
            stamps = [(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in again[topic]]
            assert stamps == [(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in source[topic]]
    clock = [m.clock.sec * 10**9 + m.clock.nanosec for _, m in again['/clock']]
    truth = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in source['/ground_truth']]
    step = truth[1] - truth[0]  # the recorder logs a step's data at the clock of the step before
    assert clock == sorted(clock) and truth[0] - step <= clock[0] and clock[-1] <= truth[-1]
    # Its stamps are on a grid of bag time, rate / (100 ticks a second) apart: no gap for a recorder to report.
    assert all((later - earlier) % 40_000_000 == 0 for earlier, later in zip(clock, clock[1:])), clock
    bag_seconds = 3.968
    print(f'\nbag play --rate 4 of a {bag_seconds} s bag: {wall:.2f} s of wall time from resume to exit '
          f'(ratio {bag_seconds / wall:.2f}; 4 expected plus start-up and matching)')


def test_a_subscriber_running_before_the_player_gets_the_first_messages_too(launch, test_node):
    """`bag play` without --start-paused to a subscriber already running: the player waits until it is matched, so
    no first message is lost (a recorder started first missed 7 of 282 /odom before it waited)."""
    from nav_msgs.msg import Odometry
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    received: list[bytes] = []
    test_node.node.create_subscription(Odometry, '/odom', received.append,
                                       QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE), raw=True)
    player = launch('bag', 'play', str(SAMPLE), '--rate', '4', '--topics', '/odom')
    expected = [data for data, _ in read_back(SAMPLE)['/odom']]
    test_node.spin_until(lambda: len(received) >= len(expected) or player.proc.poll() is not None, timeout=120,
                         what='the played /odom')
    assert wait_for_exit(player) == 0, player.output()
    try:
        test_node.spin_until(lambda: len(received) >= len(expected), timeout=30, what='the last /odom')
    except AssertionError:
        first = expected.index(received[0]) if received and received[0] in expected else None
        raise AssertionError(f'{len(received)} of {len(expected)} /odom received, the first being number {first}:\n'
                             f'{player.output()}') from None
    assert received == expected


def test_loop_replays_latched_topics_for_late_subscribers_and_ctrl_c_stops_cleanly(launch, test_node):
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String
    player = launch('bag', 'play', str(SAMPLE), '--rate', '8', '--loop', '--topics', '/world', '/ground_truth')
    odometry = test_node.collect(Odometry, '/ground_truth', 100)
    stamps = lambda: [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in odometry]  # noqa: E731
    # a loop started again once the stamps went back to the start
    test_node.spin_until(lambda: any(b < a for a, b in zip(stamps(), stamps()[1:])), timeout=90,
                         what='the bag playing a second time')
    worlds = test_node.collect(String, '/world', QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    test_node.spin_until(lambda: bool(worlds), timeout=30, what='the latched world for a late subscriber')
    assert 'arena' in worlds[0].data
    code = player.stop()
    log = player.log_path.read_text()
    assert code == 0 and 'Traceback' not in log, f'exit {code}:\n{log}'


def test_the_wait_before_the_first_message_is_said_and_chosen_with_wait(launch):
    """Issue 33 item 12: `bag play` waited 3.5 s for subscribers silently (a 3.97 s bag at 4x took 4.48 s). It says
    that it waits, for what and how long, then how long it waited; `--wait S` chooses (0: no wait)."""
    from epuck_ros.bag_cli import DEFAULT_WAIT
    from epuck_ros.ros.matching import FOREIGN_DISCOVERY_WINDOW
    assert DEFAULT_WAIT == FOREIGN_DISCOVERY_WINDOW
    # the three players at once: each waits on its own
    players = {said: launch('bag', 'play', str(SAMPLE), '--rate', '100', '--topics', '/odom',
                            *(['--wait', wait] if wait else [])) for wait, said in ((None, 'waiting 3.'),
                                                                                    ('1.5', 'waiting 1.'))}
    at_once = launch('bag', 'play', str(SAMPLE), '--rate', '100', '--topics', '/odom', '--wait', '0')
    for said, player in players.items():
        assert wait_for_exit(player) == 0, player.output()
        output = player.output()
        assert f'{said}' in output and 's for subscribers already running to show in the graph (--wait to change)' \
            in output, output
        assert 'subscriptions matched on the played topics; playing' in output, output
        assert output.index('playing') < output.index('played 125 messages in'), output
    assert wait_for_exit(at_once) == 0, at_once.output()
    assert 'waiting' not in at_once.output() and 'played 125 messages in' in at_once.output(), at_once.output()
