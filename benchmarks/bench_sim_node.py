"""The real-time factor the `sim` node reaches at `real_time_factor` 0, over DDS, with every topic subscribed.

1. one robot, every topic it publishes subscribed by this process (as a controller plus a recorder would);
2. 50 robots (`robots:=50`), every topic of every robot subscribed by this process.

The node runs in its own process (noise on, default world). Printed: simulated seconds per wall second from
`/clock`, messages received per second, the CPU each process used, and, in the same run, the pure core's steps/s
for the same number of robots (the ceiling the node's ROS overhead is measured against). The closed loop in
lockstep (sim + a behaviour) is `bench_lockstep.py`'s.

Run: . scripts/env.sh; ROS_DOMAIN_ID=42 python benchmarks/bench_sim_node.py [--seconds S] [--robots N]
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, Range
from std_msgs.msg import Float64MultiArray

from epuck_ros.bringup.processes import interrupt
from epuck_ros.model import RobotModel
from epuck_ros.simulation import Simulation
from epuck_ros.world import default_world, place_robots
from measure import cpu_seconds

STEP = 0.032
ROBOT_TOPICS = [(Odometry, 'odom'), (Odometry, 'ground_truth'), (Range, 'proximity'), (JointState, 'joint_states'),
                (Float64MultiArray, 'ir_raw')]


def executable(name: str) -> str:
    return shutil.which(name) or str(Path(sys.executable).parent / name)


def core_steps_per_second(robots: int, steps: int) -> float:
    world = default_world() if robots == 1 else place_robots(default_world(), robots, seed=0)
    sim = Simulation(world, RobotModel(), noise=True)
    for index in range(robots):
        sim.command_wheels(index, 3.0, 2.5)
    start = time.perf_counter()
    for _ in range(steps):
        sim.step()
    return steps / (time.perf_counter() - start)


def measure(seconds: float, sim_args: list[str], robots: int) -> dict:
    """Start sim, subscribe everything, measure over `seconds` of wall time."""
    sim = subprocess.Popen([executable('sim'), '--ros-args', '-p', 'real_time_factor:=0', *sim_args],
                           stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    node = Node('bench_sim_node')
    clock: list[float] = []
    received = [0]

    def on_clock(msg: Clock) -> None:
        clock.append(msg.clock.sec + msg.clock.nanosec * 1e-9)
        received[0] += 1

    def count(_msg: object) -> None:
        received[0] += 1

    node.create_subscription(Clock, '/clock', on_clock, 100)
    for prefix in [''] if robots == 1 else [f'epuck{i}/' for i in range(robots)]:
        for msg_type, topic in ROBOT_TOPICS:
            node.create_subscription(msg_type, prefix + topic, count, 100)
    try:
        deadline = time.monotonic() + 60.0
        while (len(clock) < 50) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        if not clock:
            raise SystemExit('the sim node published no /clock within 60 s')
        first_sim, start, received[0] = clock[-1], time.monotonic(), 0
        cpu_start = [cpu_seconds(sim.pid), time.process_time()]
        while time.monotonic() - start < seconds:
            rclpy.spin_once(node, timeout_sec=0.1)
        wall = time.monotonic() - start
        cpu = [cpu_seconds(sim.pid), time.process_time()]
        return {'rtf': (clock[-1] - first_sim) / wall, 'messages': received[0] / wall,
                'cpu': [(b - a) / wall for a, b in zip(cpu_start, cpu)]}
    finally:
        node.destroy_node()
        interrupt(sim, 15.0)


def report(label: str, result: dict, core: float, names: list[str]) -> None:
    cpu = ', '.join(f'{name} {share:.0%}' for name, share in zip(names, result['cpu']))
    print(f'{label:34s} {result["rtf"]:8.1f}x real time = {result["rtf"] / STEP:8,.0f} steps/s; '
          f'{result["messages"]:9,.0f} msg/s received; node/core {result["rtf"] / (core * STEP):5.2f}; CPU {cpu}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0, help='wall seconds per measurement (default 10)')
    parser.add_argument('--robots', type=int, default=50, help='robots in the swarm case (default 50)')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    core_one = core_steps_per_second(1, 20000)
    core_many = core_steps_per_second(args.robots, 2000)
    print(f'{"core alone, 1 robot":34s} {core_one * STEP:8.1f}x real time = {core_one:8,.0f} steps/s')
    print(f'{f"core alone, {args.robots} robots":34s} {core_many * STEP:8.1f}x real time = {core_many:8,.0f} steps/s')
    rclpy.init()
    try:
        one = measure(args.seconds, [], 1)
        report('sim node, 1 robot, all topics', one, core_one, ['sim', 'subscriber'])
        many = measure(args.seconds, ['-p', f'robots:={args.robots}'], args.robots)
        report(f'sim node, {args.robots} robots, all topics', many, core_many, ['sim', 'subscriber'])
    finally:
        rclpy.try_shutdown()
    print(f'goals: node 1 robot >= 100x: {"met" if one["rtf"] >= 100 else "NOT met"}; '
          f'{args.robots} robots >= 1x: {"met" if many["rtf"] >= 1 else "NOT met"}')


if __name__ == '__main__':
    main()
