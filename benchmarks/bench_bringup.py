"""The simulator as users run it, through `bringup`: the real-time factor reached and each process's CPU.

Cases (all at `--real-time-factor 0`, default world): `avoid` in lockstep (bringup's default), the same with
`--no-lockstep`, the same recorded, and a swarm (`--robots N`, one avoid process driving them all). The baseline,
measured in the same run: `sim` alone at real-time factor 0 with nothing attached but a /clock reader (what the
node can do without a controller to wait for). Each case's figures are the ones bringup prints (simulated seconds
over wall seconds from the resume on, and from the first step on: the second leaves out the run's start-up, which
held up to 1 s of the simulator's discovery window before bringup passed discovery_window:=0); CPU is user +
system seconds of each child over the command's wall time (start-up and stop included).

    python benchmarks/bench_bringup.py [--duration 30] [--robots 50]
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path
from tempfile import TemporaryDirectory

from measure import cpu_seconds, resume

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '48')

BIN = Path(sys.executable).parent
SPEED = re.compile(r'\[bringup\] simulated ([\d.]+) s in ([\d.]+) s wall \(([\d.]+)x real time\)')
STEPPING = re.compile(r'([\d.]+)x real time from the first step, which came ([\d.]+) s after the resume')


def children_of(pid: int) -> list[int]:
    found = []
    for task in Path(f'/proc/{pid}/task').glob('*'):
        try:
            found += [int(c) for c in (task / 'children').read_text().split()]
        except OSError:
            pass
    return found


def command_name(pid: int) -> str:
    try:
        words = Path(f'/proc/{pid}/cmdline').read_bytes().split(b'\0')
    except OSError:
        return '?'
    names = [Path(w.decode(errors='replace')).name for w in words[:3] if w]
    return next((n for n in names if not n.startswith('python') and n != '-m'), names[0] if names else '?')


def run_bringup(args: list[str]) -> tuple[float, str, dict[str, float]]:
    """(real-time factor bringup reports from the resume, its figure from the first step, CPU share per child)."""
    process = subprocess.Popen([str(BIN / 'bringup'), *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True)
    cpu: dict[int, tuple[str, float]] = {}
    output: list[str] = []
    reader = threading.Thread(target=lambda: output.extend(process.stdout), daemon=True)
    reader.start()
    started = time.monotonic()
    while process.poll() is None:
        for pid in [process.pid, *children_of(process.pid)]:
            used = cpu_seconds(pid)
            if used is not None:
                cpu[pid] = (cpu.get(pid, (command_name(pid), 0.0))[0], used)
        time.sleep(0.2)
    reader.join(10)
    text = ''.join(output)
    found = SPEED.search(text)
    if not found:
        raise RuntimeError(f'bringup {" ".join(args)} failed ({process.returncode}):\n{text[-3000:]}')
    for line in text.splitlines():
        if line.startswith('[bringup] error'):
            print(f'    (that run: {line})')
    wall = time.monotonic() - started
    stepping = STEPPING.search(text)
    from_first_step = f'{stepping[1]}x from the first step ({stepping[2]} s after the resume)' if stepping else ''
    return float(found[3]), from_first_step, {name: used / wall for name, used in cpu.values()
                                              if name not in ('?', 'epuck_ros.bringup.watchdog')}


def sim_alone(duration: float) -> float:
    """The node's own pace at real-time factor 0: simulated seconds per wall second, read on /clock."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    context = Context()
    rclpy.init(context=context)
    node = Node('bench_clock_reader', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stamps: list[tuple[float, float]] = []
    # Best effort: the simulator waits for reliable readers to keep up, and this one must not slow it down.
    reader = node.create_subscription(Clock, '/clock', lambda m: stamps.append(
        (time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)), QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
    sim = subprocess.Popen([str(BIN / 'sim'), '--ros-args', '-p', 'real_time_factor:=0.0', '-p', 'paused:=true',
                            '-p', f'pause_at:={duration}'], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 600
        parameters = AsyncParameterClient(node, 'sim')
        while (reader.get_publisher_count() == 0 or not parameters.services_are_ready()) and \
                time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        resume(parameters, lambda future, timeout: executor.spin_until_future_complete(future, timeout))
        while (not stamps or stamps[-1][1] < duration - 1e-6) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    finally:
        sim.send_signal(2)
        sim.wait(30)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    (wall0, sim0), (wall1, sim1) = stamps[0], stamps[-1]
    return (sim1 - sim0) / (wall1 - wall0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=30.0, help='simulated seconds per run (default 30)')
    parser.add_argument('--robots', type=int, default=50, help='robots of the swarm case (default 50)')
    options = parser.parse_args()
    duration = f'{options.duration:g}'
    print(f'bringup at --real-time-factor 0, {duration} simulated s per run; ROS_DOMAIN_ID='
          f'{os.environ["ROS_DOMAIN_ID"]}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores')
    baseline = sim_alone(options.duration)
    print(f'  baseline: sim alone (a best-effort /clock reader)   {baseline:7.1f}x real time')
    with TemporaryDirectory() as folder:
        cases = [
            ('avoid, lockstep (default)', ['avoid']),
            ('avoid, --no-lockstep', ['avoid', '--no-lockstep']),
            ('avoid, lockstep, --record', ['avoid', '--record', str(Path(folder) / 'bag')]),
            (f'avoid --robots {options.robots}, lockstep', ['avoid', '--robots', str(options.robots)]),
        ]
        for name, args in cases:
            factor, from_first_step, cpu = run_bringup([*args, '--duration', duration, '--real-time-factor', '0'])
            shares = ', '.join(f'{process} {share:.0%}' for process, share in sorted(cpu.items()))
            print(f'  {name:<40} {factor:7.1f}x real time ({factor / baseline:.2f} of the baseline; '
                  f'{from_first_step}); CPU {shares}')


if __name__ == '__main__':
    main()
