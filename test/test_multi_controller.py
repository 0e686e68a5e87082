"""Behaviour processes driving robots of a multi-robot simulator, over DDS with real processes.

The simulator runs in lockstep at full speed, started paused; the test resumes it once the controllers are in the
graph, and it pauses itself at `pause_at`: every run covers exactly the same simulated steps, however loaded the
machine. Also: the stop a behaviour commands when it ends, clean exits on the first signal, --help, typos.
"""
from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest
import yaml
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from conftest import ALONE_ON_THE_DOMAIN, EVERY_MESSAGE, ros_args, set_sim_parameter
from test_behaviour_nodes import trajectory

PAUSE_AT = 6.0
"""Simulated seconds of each run: 188 steps, 0.38 m of cruising."""
HISTORY = 1000
TIMEOUT = 60.0
"""Wall seconds any one wait may take on a very busy machine (it normally takes one or two)."""
LOCKSTEP = {**ALONE_ON_THE_DOMAIN, 'real_time_factor': 0.0, 'lockstep': True, 'paused': True, 'pause_at': PAUSE_AT,
            'seed': 4}


def three_robot_world(tmp_path: Path) -> Path:
    """The default arena with robots a, b and c, clear of the boxes and of each other."""
    world = {'arena': {'size': [1.0, 1.0]},
             'boxes': [{'position': [-0.3, 0.3], 'size': [0.1, 0.1], 'yaw': 0.0}],
             'robots': [{'name': 'a', 'start': [0.2, -0.25, 0.0]}, {'name': 'b', 'start': [0.25, 0.2, 1.6]},
                        {'name': 'c', 'start': [-0.1, -0.1, 3.1]}]}
    path = tmp_path / 'three.yaml'
    path.write_text(yaml.safe_dump(world))
    return path


class Robots:
    """The test node's view of some robots: their ground_truth, and the controls of the simulator."""

    def __init__(self, test_node: object, names: list[str]) -> None:
        self.test_node, self.names = test_node, names
        self.truth = {name: test_node.collect(Odometry, f'/{name}/ground_truth', EVERY_MESSAGE) for name in names}

    def wait_for_controllers(self, driven: list[str]) -> None:
        """Each driven robot's controller is in the graph: it publishes wheel_cmd and reads ir_raw."""
        node = self.test_node.node
        self.test_node.spin_until(
            lambda: all(node.count_publishers(f'/{name}/wheel_cmd') and node.count_subscribers(f'/{name}/ir_raw')
                        for name in driven), timeout=TIMEOUT, what=f'controllers of {driven}')

    def run_until_paused(self, sim: object) -> dict[str, np.ndarray]:
        """Resume the simulator and spin until it paused itself at PAUSE_AT; each robot's (t, x, y, yaw) rows."""
        set_sim_parameter(self.test_node, sim, 'paused', False)
        self.test_node.spin_until(lambda: all(self.sim_time(name) >= PAUSE_AT - 1e-6 for name in self.names),
                                  timeout=TIMEOUT, what=f'{PAUSE_AT} simulated seconds')
        return {name: trajectory(messages) for name, messages in self.truth.items()}

    def sim_time(self, name: str) -> float:
        messages = self.truth[name]
        return messages[-1].header.stamp.sec + 1e-9 * messages[-1].header.stamp.nanosec if messages else 0.0


def path_length(rows: np.ndarray) -> float:
    return float(np.hypot(*np.diff(rows[:, 1:3], axis=0).T).sum())


def test_one_process_drives_three_robots_the_same_way_twice(launch: object, test_node: object,
                                                            tmp_path: Path) -> None:
    """`avoid --robots a b c`: three nodes in one process, each driving its robot; two lockstep runs are identical."""
    world = three_robot_world(tmp_path)
    runs = []
    for _ in range(2):
        robots = Robots(test_node, ['a', 'b', 'c'])
        sim = launch('sim', *ros_args({**LOCKSTEP, 'world': world}))
        avoid = launch('avoid', '--robots', 'a', 'b', 'c', *ros_args({'use_sim_time': True}))
        robots.wait_for_controllers(['a', 'b', 'c'])
        # the nodes, by their parameter services: the node list comes from another channel (ros_discovery_info)
        # that once, at load average 5.7, did not show them in 60 s while their topics were there
        services = {f'/{name}/avoid/get_parameters' for name in 'abc'}
        test_node.spin_until(lambda: services <= {name for name, _ in test_node.node.get_service_names_and_types()},
                             timeout=TIMEOUT, what='nodes /a/avoid, /b/avoid, /c/avoid')
        runs.append(robots.run_until_paused(sim))
        assert 'reading the eight proximity' not in avoid.output()  # the one-message-per-step ir_raw path
        assert avoid.stop() == 0 and sim.stop() == 0
    for name in ('a', 'b', 'c'):
        first, second = runs[0][name], runs[1][name]
        print(f'robot {name}: {path_length(first):.3f} m in {PAUSE_AT} s, {len(first)} poses; second run '
              f'{path_length(second):.3f} m')
        assert path_length(first) > 0.1
        np.testing.assert_array_equal(first, second)


def test_a_namespace_remap_drives_only_that_robot(launch: object, test_node: object) -> None:
    """`avoid --ros-args -r __ns:=/epuck1` in a 3-robot simulator: epuck1 drives, the others (no controller)
    stay where they are and do not hold the lockstep simulator up."""
    robots = Robots(test_node, ['epuck0', 'epuck1', 'epuck2'])
    sim = launch('sim', *ros_args({**LOCKSTEP, 'robots': 3}))
    launch('avoid', '--ros-args', '-r', '__ns:=/epuck1', '-p', 'use_sim_time:=true')
    robots.wait_for_controllers(['epuck1'])
    rows = robots.run_until_paused(sim)
    moved = {name: path_length(rows[name]) for name in robots.names}
    print(f'distances driven: {moved}')
    assert moved['epuck1'] > 0.1
    assert moved['epuck0'] == 0.0 and moved['epuck2'] == 0.0


def test_robots_all_finds_every_robot_of_the_simulator(launch: object, test_node: object) -> None:
    """`avoid --robots all` waits for the simulator, reads its robots from the world topic, drives them all, through
    the swarm topics (one message per step each way, epuck_ros/swarm_messages.py)."""
    robots = Robots(test_node, ['epuck0', 'epuck1', 'epuck2'])
    avoid = launch('avoid', '--robots', 'all', *ros_args({'use_sim_time': True, 'cruise_speed': 1}))
    test_node.spin_until(lambda: 'waiting for the simulator' in avoid.output(), timeout=TIMEOUT,
                         what='avoid to wait for the simulator')
    sim = launch('sim', *ros_args({**LOCKSTEP, 'robots': 3}))
    node = test_node.node
    test_node.spin_until(lambda: node.count_publishers('/swarm/command') and
                         node.count_subscribers('/swarm/observation'), timeout=TIMEOUT, what='the swarm controller')
    rows = robots.run_until_paused(sim)
    assert 'cruise_speed=1.0' in avoid.output()  # an integer for a float parameter, on every robot's node
    for name in robots.names:
        assert path_length(rows[name]) > 0.1, name


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_behaviour_commands_a_stop_when_it_ends(launch: object, test_node: object, signum: int) -> None:
    """With cmd_timeout 0 the simulator never stops a robot by itself: only the behaviour's last command does.
    The simulator runs free at 10x real time, so the behaviour is busy when the signal comes; it ends with 0."""
    joints: list[JointState] = test_node.collect(JointState, '/joint_states', HISTORY)
    commands: list[Float64MultiArray] = test_node.collect(Float64MultiArray, '/wheel_cmd', HISTORY)
    launch('sim', *ros_args({'real_time_factor': 10.0, 'cmd_timeout': 0.0}))
    forward = launch('forward', *ros_args({'use_sim_time': True}))
    test_node.spin_until(lambda: commands and joints and joints[-1].velocity[0] > 1.0, timeout=TIMEOUT,
                         what='the robot to drive and the test node to hear its commands')
    forward.proc.send_signal(signum)
    test_node.spin_until(lambda: forward.proc.poll() is not None, timeout=TIMEOUT, what='forward to end')
    assert forward.proc.returncode == 0
    assert 'Traceback' not in forward.output()
    test_node.spin_until(lambda: commands and list(commands[-1].data) == [0.0, 0.0], timeout=TIMEOUT,
                         what='the last wheel command to be [0, 0]')
    test_node.spin_until(lambda: list(joints[-1].velocity) == [0.0, 0.0], timeout=TIMEOUT,
                         what='the simulated wheels to stop')
    count = len(joints)
    test_node.spin_until(lambda: len(joints) > count + 10, timeout=TIMEOUT, what='more joint states')
    assert all(list(joint.velocity) == [0.0, 0.0] for joint in joints[count:])


@pytest.mark.parametrize('name', ['forward', 'avoid'])
def test_help_says_what_the_behaviour_does_and_exits_without_driving(
        launch: object, test_node: object, name: str) -> None:
    commands: list[Float64MultiArray] = test_node.collect(Float64MultiArray, '/wheel_cmd')
    process = launch(name, '--help')
    test_node.spin_until(lambda: process.proc.poll() is not None, timeout=TIMEOUT, what=f'{name} --help to end')
    output = process.output()
    assert process.proc.returncode == 0, output
    assert 'control_period' in output and '0.032' in output and '0.001 .. 1' in output  # name, default, range
    assert '--robots' in output and 'example:' in output
    assert commands == []


@pytest.mark.parametrize('args, expected', [
    (['forward', '--ros-args', '-p', 'goal_distnace:=0.3'], 'did you mean goal_distance?'),
    (['avoid', '--robots', 'bad name'], 'bad name'),
    (['avoid', '--robots', 'a', 'a'], 'twice'),
    (['avoid', 'extra'], 'extra'),
])
def test_a_mistake_on_the_command_line_is_refused_with_one_line(launch: object, args: list[str],
                                                                expected: str) -> None:
    process = launch(*args)
    assert process.proc.wait(timeout=TIMEOUT) == 2
    output = process.output()
    assert expected in output and 'Traceback' not in output, output
