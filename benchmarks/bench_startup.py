"""Time to first motion: from typing the command to the robot moving, and where that time goes.

Measured the way users start a run: `bringup forward --real-time-factor 1` (lockstep, the default), and, as the
baseline in the same run, the stand-alone way (`sim` and `forward` started at the same moment by hand, no
bringup). An observer node in this process watches the graph and `ground_truth`; the robot moves when the true
pose first changes. Phases: the simulator node in the graph, the controller's command publisher in the graph,
bringup resuming the simulation (its `running` line), first motion. The floor is a bare rclpy process that
creates one node and is seen in the graph (interpreter, imports, DDS participant, discovery). Every process here,
the observer included, uses the package's Fast DDS profile (epuck_ros/ros/dds_profile.py).

    python benchmarks/bench_startup.py [--repeats 3]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '47')

import rclpy  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from epuck_ros.ros.dds_profile import use_package_profile  # noqa: E402

BIN = Path(sys.executable).parent
TIMEOUT = 120.0


class Observer:
    """Watches the graph and the robot's true pose; every time is in seconds since `t0`."""

    def __init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node('startup_observer', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.first_pose: tuple[float, float] | None = None
        self.sim_seen = False
        self.moved_at: float | None = None
        self.t0 = 0.0
        self.node.create_subscription(Odometry, 'ground_truth', self._on_truth, 100)

    def _on_truth(self, msg: Odometry) -> None:
        if self.t0 == 0.0 or not self.sim_seen:  # a stopping simulator's last messages, from before this one
            return
        xy = (msg.pose.pose.position.x, msg.pose.pose.position.y)
        if self.first_pose is None:
            self.first_pose = xy
        elif self.moved_at is None and xy != self.first_pose:
            self.moved_at = time.monotonic() - self.t0

    def measure(self, start: callable, extra_nodes: tuple[str, ...] = ()) -> dict[str, float]:
        """Start the processes, spin until the robot moved; returns the phase times."""
        self.first_pose, self.moved_at, self.sim_seen = None, None, False
        phases: dict[str, float] = {}
        self._wait_until_gone(('sim', 'forward', 'bringup'))
        self.t0 = time.monotonic()
        processes = start()
        try:
            while self.moved_at is None:
                self.executor.spin_once(timeout_sec=0.01)
                now = time.monotonic() - self.t0
                if 'sim in graph' not in phases and self._node_seen('sim'):
                    phases['sim in graph'] = now
                    self.sim_seen = True
                if 'controller in graph' not in phases and self.node.count_publishers('wheel_cmd') > 0:
                    phases['controller in graph'] = now
                for name in extra_nodes:
                    if f'{name} in graph' not in phases and self._node_seen(name):
                        phases[f'{name} in graph'] = now
                if now > TIMEOUT:
                    raise RuntimeError(f'no motion within {TIMEOUT} s')
            phases['first motion'] = self.moved_at
            return phases
        finally:
            self.t0 = 0.0
            for process in processes:
                process.stop()

    def _wait_until_gone(self, names: tuple[str, ...]) -> None:
        """The previous measurement's nodes must have left the graph before the next one starts."""
        deadline = time.monotonic() + TIMEOUT
        while any(self._node_seen(name) for name in names) and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def _node_seen(self, name: str) -> bool:
        return any(n == name for n, _ in self.node.get_node_names_and_namespaces())

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class Process:
    """A started executable whose output is scanned for one line (the time it appeared is kept)."""

    def __init__(self, command: list[str], t0: float, watch: str = '') -> None:
        self.proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True, env=dict(os.environ, PYTHONUNBUFFERED='1'))
        self.seen_at: float | None = None
        self._t0, self._watch = t0, watch
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            if self._watch and self.seen_at is None and self._watch in line:
                self.seen_at = time.monotonic() - self._t0

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(2)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def bare_node_seconds(observer: Observer, run: int) -> float:
    """A bare rclpy process: interpreter, imports, one node, until the observer sees it in the graph. Each run's
    node has its own name: the graph keeps a stopped process's node for a while, and a second `bare_probe` was
    'seen' at once (a floor of 0.00 s)."""
    name = f'bare_probe_{run}'
    code = (f'import rclpy, time; from rclpy.node import Node; rclpy.init(); n = Node("{name}"); '
            'time.sleep(60)')
    t0 = time.monotonic()
    process = Process([sys.executable, '-c', code], t0)
    try:
        while not observer._node_seen(name):
            observer.executor.spin_once(timeout_sec=0.01)
            if time.monotonic() - t0 > TIMEOUT:
                raise RuntimeError('bare node never seen')
        return time.monotonic() - t0
    finally:
        process.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=3)
    repeats = parser.parse_args().repeats
    use_package_profile()   # the observer and the bare node discover as the package's processes do
    observer = Observer()
    results: dict[str, list[dict[str, float]]] = {'bringup forward': [], 'sim + forward by hand': []}
    bringup_lines: list[float] = []
    floor = []
    try:
        for run in range(repeats):
            floor.append(bare_node_seconds(observer, run))
            holder: list[Process] = []

            def with_bringup() -> list[Process]:
                holder[:] = [Process([str(BIN / 'bringup'), 'forward', '--real-time-factor', '1'], observer.t0,
                                     watch='[bringup] running')]
                return holder

            phases = observer.measure(with_bringup, ('forward',))
            if holder[0].seen_at is not None:
                phases['bringup resumed the sim'] = holder[0].seen_at
                bringup_lines.append(holder[0].seen_at)
            results['bringup forward'].append(phases)

            def by_hand() -> list[Process]:
                return [Process([str(BIN / 'sim'), '--ros-args', '-p', 'real_time_factor:=1.0'], observer.t0),
                        Process([str(BIN / 'forward'), '--ros-args', '-p', 'use_sim_time:=true'], observer.t0)]

            results['sim + forward by hand'].append(observer.measure(by_hand, ('forward',)))
    finally:
        observer.close()

    load = os.getloadavg()[0]
    print(f'time to first motion, median of {repeats} (min-max), wall seconds; ROS_DOMAIN_ID='
          f'{os.environ["ROS_DOMAIN_ID"]}, load average {load:.1f} on {os.cpu_count()} cores')
    print(f'  floor: a bare rclpy node seen in the graph: {statistics.median(floor):.2f} s '
          f'({min(floor):.2f}-{max(floor):.2f})')
    for name, runs in results.items():
        print(f'  {name}:')
        for phase in sorted({p for run in runs for p in run}, key=lambda p: statistics.median(
                [run[p] for run in runs if p in run])):
            values = [run[phase] for run in runs if phase in run]
            print(f'    {phase:<26} {statistics.median(values):6.2f} s ({min(values):.2f}-{max(values):.2f})')
    bringup = statistics.median(run['first motion'] for run in results['bringup forward'])
    by_hand = statistics.median(run['first motion'] for run in results['sim + forward by hand'])
    print(f'  bringup / by hand: {bringup / by_hand:.2f}x; bringup / bare node: '
          f'{bringup / statistics.median(floor):.2f}x')


if __name__ == '__main__':
    main()
