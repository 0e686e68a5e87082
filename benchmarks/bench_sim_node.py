"""The real-time factor the `sim` node reaches with `real_time_factor` 0, publishing all its topics over DDS.

The node runs in its own process (noise on, default world) while this process listens to every topic it
publishes, as a controller and a recorder would. Printed: simulated seconds per wall second measured from
`/clock` (node), messages received per second, and, in the same run, the pure core's steps/s (the ceiling the
node's ROS overhead is measured against). The issue's goal is at least 100x real time for the node.

Run: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST python benchmarks/bench_sim_node.py [--seconds S]
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, Range

sys.path.insert(0, str(Path(__file__).parent))
from bench_core import run_core  # noqa: E402

STEP = 0.032
TOPICS = [(Clock, '/clock'), (Odometry, 'odom'), (Odometry, 'ground_truth'), (Range, 'proximity'),
          (JointState, 'joint_states')]


def measure_node(seconds: float) -> tuple[float, int]:
    """(simulated seconds per wall second, messages received) over `seconds` of wall time."""
    sim_exe = shutil.which('sim') or str(Path(sys.executable).parent / 'sim')
    sim = subprocess.Popen([sim_exe, '--ros-args', '-p', 'real_time_factor:=0.0'],
                           stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    rclpy.init()
    node = rclpy.create_node('bench_sim_node')
    clock: list[float] = []
    received = [0]

    def on_clock(msg: Clock) -> None:
        clock.append(msg.clock.sec + msg.clock.nanosec * 1e-9)
        received[0] += 1

    def count(_msg: object) -> None:
        received[0] += 1

    for msg_type, topic in TOPICS:
        node.create_subscription(msg_type, topic, on_clock if topic == '/clock' else count, 100)
    try:
        deadline = time.monotonic() + 30.0
        while not clock and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        if not clock:
            raise SystemExit('the sim node published no /clock within 30 s')
        first_sim, start, received[0] = clock[-1], time.monotonic(), 0
        while time.monotonic() - start < seconds:
            rclpy.spin_once(node, timeout_sec=0.1)
        wall = time.monotonic() - start
        return (clock[-1] - first_sim) / wall, int(received[0] / wall)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0, help='wall seconds to measure the node (default 10)')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    core_steps, _ = run_core(20000)
    print(f'core alone:          {core_steps:10,.0f} steps/s = {core_steps * STEP:6.0f}x real time')
    node_rtf, messages = measure_node(args.seconds)
    print(f'sim node (all topics): {node_rtf:8.0f}x real time = {node_rtf / STEP:8,.0f} steps/s, '
          f'{messages:,} messages/s received by one subscriber process')
    print(f'node / core:         {node_rtf / (core_steps * STEP):10.2f} (the share of time not spent on ROS)')
    print(f'goal 100x real time: {"met" if node_rtf >= 100 else "NOT met"}')


if __name__ == '__main__':
    main()
